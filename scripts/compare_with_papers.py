"""The papers' quantitative statements beside ours: paper_comparison.tsv and its figure."""

from facemotion.papers.comparison import compare, read_inputs
from facemotion.plots.comparison import plot_paper_comparison
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    paths = {}
    for key in ("selected", "rank_summary", "lip_reconstruction", "lip_counts", "lip_seeds"):
        if key in sm.input.keys():
            paths[key] = sm.input[key]
    for label, d in sm.params.datasets.items():
        for what in ("r_values", "stability", "curve", "trajectory", "coefficients"):
            name = f"{what}__{d}"
            if name in sm.input.keys():
                paths[f"{what}:{label}"] = sm.input[name]
    inputs = read_inputs(paths, lip_subject=sm.params.lip_subject or "")
    table = compare(inputs)
    write_table(table, sm.output.table, "paper_comparison", prov)
    counts = table.groupby(["paper", "verdict"]).size().to_dict()
    log.info("%d rows; verdicts: %s", len(table), counts)
    fig = plot_paper_comparison(table)
    save_figure(fig, figure_files(sm.output, "png"), "paper_comparison", prov)


run_step(snakemake, main)  # noqa: F821
