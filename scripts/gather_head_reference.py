"""A scattered streamed load, step 2: the head reference from every take's head points."""

import numpy as np

from facemotion.ingest.scatter import gather_reference
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    ds = sm.params.ds
    files = [np.load(p) for p in sm.input.heads]
    arrays = {}
    if ds["head_markers"]:
        arrays["reference"] = gather_reference([f["head"] for f in files],
                                               [float(f["rate"]) for f in files],
                                               ds["head_markers"], ds["dataset"])
        log.info("head reference from %d takes", len(files))
    write_artifact(sm.output.npz, npz_bytes(arrays), "stream_head_reference", prov)


run_step(snakemake, main)  # noqa: F821
