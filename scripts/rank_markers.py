"""Rank a dataset's markers by QR with column pivoting; epsilon-rank (paper Fig. 2)."""

import numpy as np
import pandas as pd

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.ingest.noise import estimate_noise
from facemotion.papers.lucero_munhall import EPSILON_MM
from facemotion.plots.rank import plot_r_values
from facemotion.ranking.epsilon_rank import (
    epsilon_rank_table,
    noise_epsilon,
    remainder_norms,
    singular_values,
)
from facemotion.ranking.filled import (
    describe_pivots,
    left_out_markers,
    mostly_filled_pivots,
    with_fractions,
)
from facemotion.ranking.routes import rank_for_study, ranking_summary, route_accuracy
from facemotion.regions.target import NOISE_LEVEL, headline_facts
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    p = sm.params
    train, held = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    ranking = rank_for_study(train.A, train.labels, method=p.method, k_max=p.k_max)
    norm = p.r_normalisation
    table = ranking.to_frame(norm)  # |r_kk| in the three readings of Fig. 2, and the chosen
    # beside them sigma_k and ||R22||_2 before pivot k (L&M Sec. III: sigma_{k+1} <= ||R22||_2)
    table["singular_value"] = singular_values(ranking)
    table["remainder_norm"] = remainder_norms(ranking)
    gap_report = pd.read_csv(sm.input.gap_report, sep="\t", dtype={"marker": str},
                             keep_default_na=False)
    table = with_fractions(table, gap_report)  # how much of each marker is made up
    mostly_filled = mostly_filled_pivots(table, p.flag_pivots, p.flag_filled_fraction)
    flagged = describe_pivots(mostly_filled)
    if flagged:
        log.warning("mostly filled among the first %d pivots (more than %g of the frames "
                    "made up by gap filling): %s", p.flag_pivots, p.flag_filled_fraction,
                    flagged)
    write_table(table, sm.output.r_values, "r_values", prov)
    write_table(table.head(p.top_n), sm.output.r_values_top, "r_values", prov)
    summary = ranking_summary(ranking, int(np.count_nonzero(~train.A.any(axis=1))))
    if summary["note"]:
        log.warning("%s", summary["note"])
    if p.route_check and ranking.method == "randomized":  # vs pivoted QR at the same k
        acc = route_accuracy(train.A, ranking)
        summary["residual_ratio_vs_qr"] = ";".join(
            f"k={k}:{r:.4f}" for k, r in zip(acc["k"], acc["ratio"], strict=True))
    # for a lab: how many markers predict the rest within the target, and the data's noise
    noise = estimate_noise(train)
    summary.update(headline_facts(ranking, held, target_mm=p.target_mm,
                                  resamples=p.resamples, level=p.level, k_max=p.k_max))
    summary.update(noise_mm=noise.noise_mm, noise_source=noise.source)
    log.info("noise per coordinate: %.3g mm (high-frequency residual %.3g mm over %d frames, "
             "head-fit residual %.3g mm); k for %g mm held-out error: %s", noise.noise_mm,
             noise.high_frequency_mm, noise.window_frames, noise.head_fit_mm, p.target_mm,
             summary["k_for_target"])
    # the setting's tolerances, the paper's epsilon for the comparison with the paper, and the
    # tolerance at the data's own noise level
    extra = {EPSILON_MM: "L&M Sec. IV (paper comparison)"}
    if np.isfinite(noise.noise_mm) and noise.noise_mm > 0:
        extra[noise_epsilon(noise.noise_mm, ranking.rows, ranking.n, norm)] = NOISE_LEVEL
    rank = epsilon_rank_table(ranking, list(p.tolerances_mm), norm, summary, extra=extra)
    rank["mostly_filled_pivots"] = flagged
    rank["left_out_filled"] = ", ".join(left_out_markers(gap_report))
    write_table(rank, sm.output.rank, "rank", prov)
    log.info("R normalisation %r; epsilon-rank (smallest k with ||R22||_2 <= epsilon) and the "
             "diagonal count: %s", norm,
             rank[["tolerance_mm", "epsilon_rank", "diagonal_count"]].to_dict("records"))
    fig = plot_r_values({p.label: table}, tolerances=tuple(p.tolerances_mm),
                        flagged={p.label: mostly_filled})
    save_figure(fig, figure_files(sm.output, "png"), "r_values", prov)


run_step(snakemake, main)  # noqa: F821
