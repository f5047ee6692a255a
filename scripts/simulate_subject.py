"""Write each virtual subject as C3D files (one per sentence) plus its ground truth; the dense
talker (designs D468, D5023) in the subject's format, plus its mesh. One job for all of them."""

from pathlib import Path

from facemotion.io.c3d import write_c3d
from facemotion.study.adapter import run_per_dataset
from facemotion.study.provenance import write_artifact
from facemotion.virtual.dense import DENSE_DESIGNS, simulate_dense, write_dense_subject
from facemotion.virtual.talker import simulate_subject, truth_npz_bytes


def main(sm, log, prov):
    p = dict(sm.params.sim)
    out = Path(sm.output.dirs)
    sid = sm.wildcards.dataset  # the subject (run_per_dataset's item)
    out.mkdir(parents=True, exist_ok=True)
    kwargs = {"seed": p["seed"], "n_sentences": p["n_sentences"],
              "talker_seed": p["talker_seed"]}
    if p.get("sentence_duration"):
        kwargs["sentence_duration"] = tuple(p["sentence_duration"])
    if p["design"] in DENSE_DESIGNS:  # the dense talker: TRC, C3D or OpenFace CSV, mesh.obj
        subject = simulate_dense(p["design"], shared_data=p["shared_data"], **kwargs)
        for path in write_dense_subject(subject, out, sid, p["format"]):
            log.info("wrote %s", path.name)
        write_artifact(out / "truth.npz", truth_npz_bytes(subject), "virtual_truth", prov)
        return
    subject = simulate_subject(p["design"], **kwargs)
    takes = []
    for i, (rec, name) in enumerate(zip(subject.recordings, subject.names, strict=True)):
        takes.append(out / f"{sid}_s{i + 1:02d}.c3d")
        write_c3d(takes[-1], rec)
        log.info("wrote sentence %d/%d (%s)", i + 1, len(subject.names), name)
    write_artifact(out / "truth.npz", truth_npz_bytes(subject), "virtual_truth", prov,
                   also=takes)


run_per_dataset(snakemake, main, cost=lambda part: part.params.sim["n_sentences"],  # noqa: F821
                preload=("scipy.spatial",))  # the talkers' face geometry
