"""Rank markers by QR with column pivoting; epsilon-rank (paper Fig. 2)."""

from facemotion.displacements import load_displacements
from facemotion.loading import split_roles
from facemotion.pivoted_qr import epsilon_rank, rank_markers
from facemotion.plots.rank import plot_r_values
from facemotion.provenance import save_figure, write_table
from facemotion.snakemake_adapter import figure_paths, run_step


def main(sm, log, prov):
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    ranking = rank_markers(train.A, train.labels, method=sm.params.method)
    norm = sm.params.r_normalisation
    table = ranking.to_frame(norm)  # |r_kk| in the three readings of Fig. 2, and the chosen
    write_table(table, sm.output.r_values, "r_values", prov)
    rank = epsilon_rank(ranking, list(sm.params.tolerances_mm), normalisation=norm)
    write_table(rank, sm.output.rank, "rank", prov)
    log.info("R normalisation %r; epsilon-rank (smallest k with ||R22||_2 <= epsilon) and the "
             "diagonal count: %s", norm, rank.drop(columns="redundant_markers").to_dict("records"))
    fig = plot_r_values({sm.params.label: table}, tolerances=tuple(sm.params.tolerances_mm))
    save_figure(fig, figure_paths(sm.output, "png"), "r_values", prov)


run_step(snakemake, main)  # noqa: F821
