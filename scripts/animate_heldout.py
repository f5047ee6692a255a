"""Animate held-out sentences: the face driven by the k main markers beside the measured one."""

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.io.atomic import atomic_write_bytes
from facemotion.plots.animation import FaceAnimation, animation_page, heldout_clip, write_animation
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
    clip = heldout_clip(part, predict(ranking, k, part.A), cfg["fps"], sm.params.label)
    log.info("animating %d frames of %d held-out sentence(s) at %.1f fps", len(clip.captions),
             n, clip.fps)
    anim = FaceAnimation(d.neutral, clip.measured, clip.model, d.labels, main_markers,
                         grid_n=cfg["grid_n"])
    write_animation(sm.output.anim, anim.frames(clip.captions), clip.fps)
    sidecar_for_existing(sm.output.anim, "animation", prov)
    atomic_write_bytes(sm.output.page, animation_page(
        sm.output.anim, f"{sm.params.label}: measured face (left) and face predicted from the "
        f"k = {k} main markers (right, red dots), {len(clip.captions)} frames at {clip.fps:g} "
        "fps", f"main markers: {', '.join(main_markers)}"))
    sidecar_for_existing(sm.output.page, "animation_page", prov)
    peak = clip.largest_motion
    fig = anim.still(peak, clip.captions[peak] + " - largest motion")
    save_figure(fig, figure_files(sm.output, "png"), "animation_still", prov)


run_step(snakemake, main)  # noqa: F821
