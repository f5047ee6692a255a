"""Write a virtual subject as real files (one per sentence) plus its ground truth."""

from pathlib import Path

from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact
from facemotion.virtual.files import write_virtual_subject


def main(sm, log, prov):
    p = dict(sm.params.sim)
    out = Path(sm.output[0])
    paths, truth = write_virtual_subject(
        out, sm.wildcards.subject, p["design"], fmt=p["format"], seed=p["seed"],
        n_sentences=p["n_sentences"], talker_seed=p["talker_seed"],
        sentence_duration=p["sentence_duration"], shared_data=p["shared_data"])
    write_artifact(out / "truth.npz", truth, "virtual_truth", prov, also=paths)


run_step(snakemake, main)  # noqa: F821
