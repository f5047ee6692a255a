"""Write a virtual subject as C3D files (one per sentence) plus its ground truth."""

from pathlib import Path

from facemotion.provenance import write_artifact
from facemotion.readers import write_c3d
from facemotion.snakemake_adapter import run_step
from facemotion.synth import simulate_subject, truth_npz_bytes


def main(sm, log, prov):
    p = dict(sm.params.sim)
    out = Path(sm.output[0])
    out.mkdir(parents=True, exist_ok=True)
    kwargs = {"seed": p["seed"], "n_sentences": p["n_sentences"],
              "talker_seed": p["talker_seed"]}
    if p.get("sentence_duration"):
        kwargs["sentence_duration"] = tuple(p["sentence_duration"])
    subject = simulate_subject(p["design"], **kwargs)
    for i, (rec, name) in enumerate(zip(subject.recordings, subject.names, strict=True)):
        write_c3d(out / f"{sm.wildcards.subject}_s{i + 1:02d}.c3d", rec)
        log.info("wrote sentence %d/%d (%s)", i + 1, len(subject.names), name)
    write_artifact(out / "truth.npz", truth_npz_bytes(subject), "virtual_truth", prov)


run_step(snakemake, main)  # noqa: F821
