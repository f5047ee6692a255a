"""Held-out error curves of all datasets overlaid (paper Fig. 10)."""

import pandas as pd

from facemotion.plots.errors import plot_error_curves
from facemotion.provenance import save_figure
from facemotion.snakemake_adapter import figure_paths, run_step


def main(sm, log, prov):
    curves = {lab: pd.read_csv(p, sep="\t")
              for lab, p in zip(sm.params.labels, sm.input.curves, strict=True)}
    fig = plot_error_curves(curves)
    save_figure(fig, figure_paths(sm.output, "png"), "error_curves_all", prov)


run_step(snakemake, main)  # noqa: F821
