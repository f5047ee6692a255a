"""Rank markers by QR with column pivoting; epsilon-rank (paper Fig. 2)."""

import pandas as pd

from facemotion.displacements import load_displacements
from facemotion.loading import split_roles
from facemotion.pivoted_qr import epsilon_rank, rank_markers
from facemotion.plots.rank import plot_r_values
from facemotion.provenance import save_figure, write_table
from facemotion.snakemake_adapter import run_step


def r_values_table(ranking, normalisation):
    """|r_kk| in the three readings of Fig. 2's normalisation, and the chosen one."""
    return pd.DataFrame({
        "order": range(1, len(ranking.r) + 1),
        "marker": ranking.labels_in_order,
        "r": ranking.r,
        "r_rms": ranking.normalised_r("per_coordinate"),
        "r_rms_frame": ranking.normalised_r("per_frame"),
        "r_normalised": ranking.normalised_r(normalisation),
        "r_normalisation": normalisation,
        # False past the pivots the QR rule chose (fewer rows than markers, or k_max)
        "ranked": [i < ranking.n_ranked for i in range(len(ranking.r))],
    })


def main(sm, log, prov):
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    ranking = rank_markers(train.A, train.labels, method=sm.params.method)
    norm = sm.params.r_normalisation
    table = r_values_table(ranking, norm)
    write_table(table, sm.output.r_values, "r_values", prov)
    rank = epsilon_rank(ranking, list(sm.params.tolerances_mm), normalisation=norm)
    write_table(rank, sm.output.rank, "rank", prov)
    log.info("R normalisation %r; epsilon-rank (smallest k with ||R22||_2 <= epsilon) and the "
             "diagonal count: %s", norm, rank.drop(columns="redundant_markers").to_dict("records"))
    fig = plot_r_values({sm.params.label: table}, tolerances=tuple(sm.params.tolerances_mm))
    save_figure(fig, [sm.output.png, sm.output.pdf], "r_values", prov)


run_step(snakemake, main)  # noqa: F821
