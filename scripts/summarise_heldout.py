"""Held-out error curves of all datasets overlaid (paper Fig. 10)."""

import pandas as pd

from facemotion.plots.error_curves import plot_error_curves
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure


def main(sm, log, prov):
    curves = {label: pd.read_csv(p, sep="\t")
              for label, p in zip(sm.params.labels, sm.input.curves, strict=True)}
    fig = plot_error_curves(curves)
    save_figure(fig, figure_files(sm.output, "png"), "error_curves_all", prov)


run_step(snakemake, main)  # noqa: F821
