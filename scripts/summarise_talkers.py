"""How stable are the paper's conclusions across virtual talkers?"""

import pandas as pd

from facemotion.plots.cross_subject import plot_talkers
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table
from facemotion.study.sweeps import talker_summary, top_k_frequency


def main(sm, log, prov):
    talkers = list(sm.params.talkers)
    r_values = {t: pd.read_csv(p, sep="\t", dtype={"marker": str})
                for t, p in zip(talkers, sm.input.r_values, strict=True)}
    curves = {t: pd.read_csv(p, sep="\t") for t, p in zip(talkers, sm.input.curves, strict=True)}
    table, selected = talker_summary(r_values, curves)
    write_table(table, sm.output.talkers, "summary", prov)
    freq = top_k_frequency(selected, k=10)
    write_table(freq, sm.output.talkers_top10, "summary", prov)
    fig = plot_talkers(table, freq)
    save_figure(fig, figure_files(sm.output, "png"), "talkers", prov)


run_step(snakemake, main)  # noqa: F821
