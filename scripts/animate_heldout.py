"""Animate held-out sentences: the face driven by the k main markers beside the measured one."""

import math

import numpy as np

from facemotion.animation import render_frames, still_frame, write_animation
from facemotion.displacements import load_displacements
from facemotion.loading import split_roles
from facemotion.pivoted_qr import rank_markers
from facemotion.prediction import predict
from facemotion.provenance import save_figure, sidecar_for_existing
from facemotion.snakemake_adapter import run_step


def main(sm, log, prov):
    cfg = sm.params.animation
    d = load_displacements(sm.input.npz)
    train, held = split_roles(d, sm.input.sentences)
    ranking = rank_markers(train.A, train.labels, method=sm.params.method)
    k = cfg["k"]  # k and sentences are checked against the data at parse time
    main_markers = ranking.labels_in_order[:k]
    n = cfg["sentences"]
    part = held.subset(list(range(n)))
    pred = predict(ranking, k, part.A)
    measured = part.A.reshape(-1, 3, len(d.labels)).transpose(0, 2, 1)
    model = pred.reshape(-1, 3, len(d.labels)).transpose(0, 2, 1)
    step = math.ceil(part.rate / cfg["fps"] - 1e-9)  # every step-th frame: at most fps
    idx = np.arange(0, measured.shape[0], step)
    fps = part.rate / step
    log.info("animating %d frames of %d held-out sentence(s) at %.1f fps", len(idx), n, fps)
    frames = render_frames(d.neutral, measured[idx], model[idx], d.labels, main_markers,
                           fps=fps, grid_n=cfg["grid_n"])
    write_animation(sm.output.anim, frames, fps)
    sidecar_for_existing(sm.output.anim, "animation", prov)
    peak = int(np.argmax(np.abs(measured[idx]).sum(axis=(1, 2))))
    fig = still_frame(d.neutral, measured[idx][peak], model[idx][peak], d.labels, main_markers,
                      grid_n=cfg["grid_n"])
    save_figure(fig, [sm.output.png, sm.output.pdf], "animation_still", prov)


run_step(snakemake, main)  # noqa: F821
