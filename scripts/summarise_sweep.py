"""Cross-dataset summary of a parameter sweep, with its figure."""

import pandas as pd

from facemotion.plots.cross_subject import plot_sweep_summary
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    table = pd.concat([pd.read_csv(p, sep="\t", dtype={"redundant_markers": str,
                                                       "first_pivots": str, "point": str},
                                   keep_default_na=False, na_values=[""])
                       for p in sm.input], ignore_index=True)
    # inputs come in grid order within each dataset; keep it
    table = table.sort_values(["dataset"], kind="stable").reset_index(drop=True)
    write_table(table, sm.output.table, "summary", prov)
    fig = plot_sweep_summary(table, title=f"sweep {sm.wildcards.sweep}")
    save_figure(fig, figure_files(sm.output, "png"), "sweep_summary", prov)


run_step(snakemake, main)  # noqa: F821
