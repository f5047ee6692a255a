"""A scattered streamed load, step 2: the head reference from every take's head points, and the
copy_markers pairs' median offsets."""

import numpy as np

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.scatter import gather_copy_medians, gather_reference
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    ds = sm.params.ds
    files = [np.load(p) for p in sm.input.heads]
    arrays = {}
    reference = None
    if ds["head_markers"]:
        reference = gather_reference([f["head"] for f in files],
                                     [float(f["rate"]) for f in files],
                                     ds["head_markers"], ds["dataset"])
        arrays["reference"] = reference
        log.info("head reference from %d takes", len(files))
    pairs = parse_copy_markers(ds["copy_markers"], "copy_markers")
    if pairs:
        arrays["copy_medians"] = gather_copy_medians(
            [[f[f"pair{j}"] for j in range(len(pairs))] for f in files], pairs,
            float(files[0]["rate"]), ds["head_markers"], reference)
        log.info("copy_markers: median offsets of %d pair(s) over %d takes", len(pairs),
                 len(files))
    write_artifact(sm.output.npz, npz_bytes(arrays), "stream_head_reference", prov)


run_step(snakemake, main)  # noqa: F821
