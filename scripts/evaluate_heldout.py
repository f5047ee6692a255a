"""Held-out error against k (paper Fig. 10) and a measured-vs-model trajectory (Fig. 9)."""

from facemotion.errors import InputError
from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.plots.error_curves import plot_error_curves, plot_trajectory
from facemotion.ranking.routes import rank_for_study
from facemotion.regions.prediction import error_curve
from facemotion.regions.trajectory import heldout_trajectory
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    p = sm.params
    train, held = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    if held is None:
        raise InputError(f"dataset {sm.wildcards.dataset}: no held-out sentences to evaluate")
    ranking = rank_for_study(train.A, train.labels, method=p.method, k_max=p.k_max)
    curve = error_curve(ranking, held.A, held.labels, k_max=p.k_max)
    log.info("error curve for k = 1..%d (qr.k_max %s, numerical rank %d)", len(curve) - 1,
             p.k_max, ranking.numerical_rank())
    write_table(curve, sm.output.curve, "error_curve", prov)
    fig = plot_error_curves({p.label: curve}, n_markers={p.label: len(held.labels)})
    save_figure(fig, figure_files(sm.output, "png"), "error_curve", prov)
    # k and the sentence are checked against the markers and held-out sentences at parse time
    traj = heldout_trajectory(ranking, p.k, held, requested=p.marker,
                              sentence_number=p.sentence)
    write_table(traj.table(), sm.output.traj, "trajectory_errors", prov)
    fig = plot_trajectory(traj.time_s, traj.measured, traj.model, marker=traj.marker,
                          sentence=traj.sentence, k=traj.k, in_basis=traj.in_basis,
                          note=traj.note)
    save_figure(fig, figure_files(sm.output, "traj_png"), "trajectory", prov)


run_step(snakemake, main)  # noqa: F821
