"""Stability of R against the number of sentences (paper Fig. 3)."""

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.plots.sweep import plot_sentence_sweep
from facemotion.ranking.stability import sentence_sweep, stability
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    p = sm.params
    sweep = sentence_sweep(train.A, train.labels, train.row_sentence, n_pivots=p.n_pivots)
    write_table(sweep, sm.output.sentence_sweep, "sentence_sweep", prov)
    log.info("stability: %d replicates", p.replicates)
    result = stability(train.A, train.labels, train.row_sentence, n_pivots=p.n_pivots,
                       tolerance=p.settle_tolerance, k_agree=tuple(p.agreement_k),
                       n_replicates=p.replicates, seed=p.seed)
    write_table(result.settling, sm.output.stability, "stability", prov)
    write_table(result.agreement, sm.output.stability_agreement, "stability", prov)
    fig = plot_sentence_sweep(sweep, settling=result.settling, tolerance=p.settle_tolerance)
    save_figure(fig, figure_files(sm.output, "png"), "sentence_sweep", prov)


run_step(snakemake, main)  # noqa: F821
