"""Held-out error against k (paper Figs. 9-10) and a measured-vs-model trajectory."""

import numpy as np
import pandas as pd

from facemotion.displacements import load_displacements
from facemotion.errors import InputError
from facemotion.loading import split_roles
from facemotion.pivoted_qr import rank_markers
from facemotion.plots.errors import plot_error_curves, plot_trajectory
from facemotion.prediction import error_curve, predict
from facemotion.provenance import save_figure, write_table
from facemotion.snakemake_adapter import run_step


def main(sm, log, prov):
    p = sm.params
    train, held = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    if held is None:
        raise InputError(f"dataset {sm.wildcards.dataset}: no held-out sentences to evaluate")
    ranking = rank_markers(train.A, train.labels, method=p.method)
    curve = error_curve(ranking, held.A, held.labels)
    write_table(curve, sm.output.curve, "error_curve", prov)
    fig = plot_error_curves({p.label: curve})
    save_figure(fig, [sm.output.png, sm.output.pdf], "error_curve", prov)

    # Trajectory of one marker in one held-out sentence, model with k main markers.
    k = min(p.k, len(held.labels) - 1)
    main_markers = ranking.labels_in_order[:k]
    marker = p.marker
    s = min(p.sentence, len(held.sentences)) - 1
    one = held.subset([s])
    if marker is None or marker not in held.labels or marker in main_markers:
        # the secondary marker that moves most in this sentence
        secondary = [m for m in one.labels if m not in main_markers]
        motion = {m: float(np.sum(one.A[:, one.labels.index(m)] ** 2)) for m in secondary}
        fallback = max(secondary, key=lambda m: (motion[m], m))
        log.info("trajectory marker %r unavailable or a main marker at k=%d; using %s, the "
                 "secondary marker that moves most", marker, k, fallback)
        marker = fallback
    pred = predict(ranking, k, one.A)
    j = one.labels.index(marker)
    measured = one.A[:, j].reshape(-1, 3)
    model = pred[:, j].reshape(-1, 3)
    t = np.arange(measured.shape[0]) / one.rate
    errs = np.abs(measured - model).max(axis=0)
    table = pd.DataFrame({"marker": marker, "sentence": one.sentences[0], "k": k,
                          "axis": ["x", "y", "z"], "max_abs_error_mm": errs})
    write_table(table, sm.output.traj, "trajectory_errors", prov)
    fig = plot_trajectory(t, measured, model, marker=marker, sentence=one.sentences[0], k=k)
    save_figure(fig, [sm.output.traj_png, sm.output.traj_pdf], "trajectory", prov)


run_step(snakemake, main)  # noqa: F821
