"""Selected markers across datasets (paper Table I), epsilon-ranks, Fig. 2 overlaid."""

import pandas as pd

from facemotion.plots.rank import plot_r_values
from facemotion.plots.selection import plot_selection_agreement
from facemotion.ranking.filled import mostly_filled_pivots
from facemotion.ranking.result import selection_table
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    labels = list(sm.params.labels)
    r_tables = {lab: pd.read_csv(p, sep="\t", dtype={"marker": str})
                for lab, p in zip(labels, sm.input.r_values, strict=True)}
    n = sm.params.table_orders
    table = selection_table({lab: t["marker"] for lab, t in r_tables.items()}, n)
    write_table(table, sm.output.selected_markers, "selected_markers", prov)
    fig = plot_selection_agreement(table, k=min(10, n))
    save_figure(fig, figure_files(sm.output, "selected_png"), "selected_markers", prov)
    ranks = []
    for lab, p in zip(labels, sm.input.rank, strict=True):
        r = pd.read_csv(p, sep="\t", dtype={"redundant_markers": str}, keep_default_na=False)
        r.insert(0, "dataset", lab)
        ranks.append(r)
    write_table(pd.concat(ranks, ignore_index=True), sm.output.rank_summary, "summary", prov)
    flagged = {lab: mostly_filled_pivots(t, sm.params.flag_pivots,
                                         sm.params.flag_filled_fraction)
               for lab, t in r_tables.items() if "filled_fraction" in t}
    fig = plot_r_values(r_tables, tolerances=tuple(sm.params.tolerances_mm), flagged=flagged)
    save_figure(fig, figure_files(sm.output, "r_values_png"), "r_values_all", prov)


run_step(snakemake, main)  # noqa: F821
