"""Held-out error against k (paper Fig. 10) and a measured-vs-model trajectory (Fig. 9)."""

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.plots.error_curves import plot_error_curves, plot_trajectory
from facemotion.ranking.routes import rank_for_study
from facemotion.regions.prediction import error_curve, predict
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

    # Trajectory of one marker in one held-out sentence, model with k main markers.
    k = p.k  # checked against the markers at parse time (never clamped)
    main_markers = ranking.labels_in_order[:k]
    marker = p.marker
    s = p.sentence - 1  # checked against the held-out sentences at parse time
    one = held.subset([s])
    requested = marker
    if marker is None or marker not in held.labels:
        # no marker requested, or the requested one (default 56, the paper's) is not in this
        # dataset: the secondary marker that moves most in this sentence, said in the log, the
        # table and the figure
        secondary = [m for m in one.labels if m not in main_markers]
        motion = {m: float(np.sum(one.A[:, one.labels.index(m)] ** 2)) for m in secondary}
        marker = max(secondary, key=lambda m: (motion[m], m))
        log.warning("eval.trajectory_marker %r %s: drawing %s, the secondary marker that moves "
                    "most in %s", requested,
                    "not set" if requested is None else "is not in this dataset", marker,
                    one.sentences[0])
    in_basis = marker in main_markers
    if in_basis:
        log.warning("trajectory marker %s is one of the %d main markers (pivot %d): the model "
                    "copies it and its error is zero; the figure says so", marker, k,
                    main_markers.index(marker) + 1)
    else:
        log.info("trajectory marker %s is a secondary marker at k = %d", marker, k)
    pred = predict(ranking, k, one.A)
    j = one.labels.index(marker)
    measured = one.A[:, j].reshape(-1, 3)
    model = pred[:, j].reshape(-1, 3)
    t = np.arange(measured.shape[0]) / one.rate
    errs = np.abs(measured - model).max(axis=0)
    table = pd.DataFrame({"marker": marker, "requested_marker": requested or "",
                          "sentence": one.sentences[0], "k": k, "in_basis": in_basis,
                          "axis": ["x", "y", "z"], "max_abs_error_mm": errs})
    write_table(table, sm.output.traj, "trajectory_errors", prov)
    fig = plot_trajectory(t, measured, model, marker=marker, sentence=one.sentences[0], k=k,
                          in_basis=in_basis,
                          note=None if requested == marker else
                          f"marker {requested} requested, not in this dataset" if requested
                          else "no marker requested: the secondary marker that moves most")
    save_figure(fig, figure_files(sm.output, "traj_png"), "trajectory", prov)



run_step(snakemake, main)  # noqa: F821
