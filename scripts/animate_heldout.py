"""Animate held-out sentences: the face driven by the k main markers beside the measured one."""

import numpy as np

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.io.atomic import atomic_write_bytes
from facemotion.plots.animation import FaceAnimation, animation_page, frame_indices, write_animation
from facemotion.ranking.routes import rank_for_study
from facemotion.regions.prediction import predict
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, sidecar_for_existing


def main(sm, log, prov):
    cfg = sm.params.animation
    d = load_displacements(sm.input.npz)
    train, held = split_roles(d, sm.input.sentences)
    ranking = rank_for_study(train.A, train.labels, method=sm.params.method,
                             k_max=sm.params.k_max)
    k = cfg["k"]  # k and sentences are checked against the data at parse time
    main_markers = ranking.labels_in_order[:k]
    n = cfg["sentences"]
    part = held.subset(list(range(n)))
    pred = predict(ranking, k, part.A)
    measured = part.A.reshape(-1, 3, len(d.labels)).transpose(0, 2, 1)
    model = pred.reshape(-1, 3, len(d.labels)).transpose(0, 2, 1)
    idx, fps = frame_indices(measured.shape[0], part.rate, cfg["fps"])
    # each frame names its held-out sentence, its frame there and the time in the sentence
    sent = part.row_sentence[::3][idx]
    frame = part.row_frame[::3][idx]
    n_in = {s: int(np.sum(part.row_sentence[::3] == s)) for s in set(sent.tolist())}
    captions = [f"{sm.params.label}: held-out sentence {part.sentences[s]}, frame {f + 1} of "
                f"{n_in[s]} (t = {f / part.rate:.2f} s)" for s, f in zip(sent, frame, strict=True)]
    log.info("animating %d frames of %d held-out sentence(s) at %.1f fps", len(idx), n, fps)
    anim = FaceAnimation(d.neutral, measured[idx], model[idx], d.labels, main_markers,
                         grid_n=cfg["grid_n"])
    write_animation(sm.output.anim, anim.frames(captions), fps)
    sidecar_for_existing(sm.output.anim, "animation", prov)
    atomic_write_bytes(sm.output.page, animation_page(
        sm.output.anim, f"{sm.params.label}: measured face (left) and face predicted from the "
        f"k = {k} main markers (right, red dots), {len(idx)} frames at {fps:g} fps",
        f"main markers: {', '.join(main_markers)}"))
    sidecar_for_existing(sm.output.page, "animation_page", prov)
    peak = int(np.argmax(np.abs(measured[idx]).sum(axis=(1, 2))))
    fig = anim.still(peak, captions[peak] + " - largest motion")
    save_figure(fig, figure_files(sm.output, "png"), "animation_still", prov)


run_step(snakemake, main)  # noqa: F821
