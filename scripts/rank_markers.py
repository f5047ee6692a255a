"""Rank markers by QR with column pivoting; epsilon-rank (paper Fig. 2); then the selected
markers of all datasets together (Table I) and Fig. 2 overlaid."""

import numpy as np
import pandas as pd

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.plots.rank import plot_r_values
from facemotion.plots.selection import plot_selection_agreement
from facemotion.ranking.epsilon_rank import epsilon_rank
from facemotion.ranking.routes import rank_for_study, ranking_summary, route_accuracy
from facemotion.regions.selector import selection_table
from facemotion.study.adapter import across_provenance, figure_paths, run_per_dataset
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    p = sm.params
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    ranking = rank_for_study(train.A, train.labels, method=p.method, k_max=p.k_max)
    norm = p.r_normalisation
    table = ranking.to_frame(norm)  # |r_kk| in the three readings of Fig. 2, and the chosen
    write_table(table, sm.output.r_values, "r_values", prov)
    write_table(table.head(p.top_n), sm.output.r_values_top, "r_values", prov)
    rank = epsilon_rank(ranking, list(p.tolerances_mm), normalisation=norm)
    summary = ranking_summary(ranking, int(np.count_nonzero(~train.A.any(axis=1))))
    if summary["note"]:
        log.warning("%s", summary["note"])
    if p.route_check and ranking.method == "randomized":  # vs pivoted QR at the same k
        acc = route_accuracy(train.A, ranking)
        summary["residual_ratio_vs_qr"] = ";".join(
            f"k={k}:{r:.4f}" for k, r in zip(acc["k"], acc["ratio"], strict=True))
    for key, value in summary.items():  # the same facts in the table
        rank.insert(len(rank.columns) - 1, key, value)
    write_table(rank, sm.output.rank, "rank", prov)
    log.info("R normalisation %r; epsilon-rank (smallest k with ||R22||_2 <= epsilon) and the "
             "diagonal count: %s", norm,
             rank[["tolerance_mm", "epsilon_rank", "diagonal_count"]].to_dict("records"))
    fig = plot_r_values({p.label: table}, tolerances=tuple(p.tolerances_mm))
    save_figure(fig, figure_paths(sm.output, "png"), "r_values", prov)


def across(sm, log):
    """Selected markers across datasets (paper Table I), epsilon-ranks, Fig. 2 overlaid."""
    labels = [sm.params.per_dataset[d]["label"] for d in sm.params.datasets]
    prov = across_provenance(sm, [*sm.output.r_values, *sm.output.rank])
    r_tables = {lab: pd.read_csv(p, sep="\t", dtype={"marker": str})
                for lab, p in zip(labels, sm.output.r_values, strict=True)}
    n = sm.params.across_orders
    table = selection_table({lab: t["marker"] for lab, t in r_tables.items()}, n)
    write_table(table, sm.output.across_table, "selected_markers", prov)
    fig = plot_selection_agreement(table, k=min(10, n))
    save_figure(fig, figure_paths(sm.output, "across_sel_png"), "selected_markers", prov)
    ranks = []
    for lab, p in zip(labels, sm.output.rank, strict=True):
        r = pd.read_csv(p, sep="\t", dtype={"redundant_markers": str}, keep_default_na=False)
        r.insert(0, "dataset", lab)
        ranks.append(r)
    write_table(pd.concat(ranks, ignore_index=True), sm.output.across_summary, "summary", prov)
    fig = plot_r_values(r_tables, tolerances=tuple(sm.params.tolerances_mm))
    save_figure(fig, figure_paths(sm.output, "across_png"), "r_values_all", prov)


run_per_dataset(snakemake, main, across)  # noqa: F821
