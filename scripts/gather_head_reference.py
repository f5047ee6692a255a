"""A scattered streamed load, step 2: the head reference from every sentence's head points, and
the copy_markers pairs' median offsets."""

import numpy as np

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.scatter import by_position, gather_copy_medians, gather_reference
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    ds = sm.params.ds
    pairs = parse_copy_markers(ds["copy_markers"], "copy_markers")
    takes = [dict(np.load(p)) for p in sm.input.heads]
    heads, pair_points, rates = by_position(takes, len(pairs))
    arrays, reference = {}, None
    if ds["head_markers"]:
        reference = gather_reference(heads, rates, ds["head_markers"], ds["dataset"])
        arrays["reference"] = reference
        log.info("head reference from %d sentences of %d takes", len(heads), len(takes))
    if pairs:
        arrays["copy_medians"] = gather_copy_medians(pair_points, pairs, rates[0],
                                                     ds["head_markers"], reference)
        log.info("copy_markers: median offsets of %d pair(s) over %d sentences", len(pairs),
                 len(heads))
    write_artifact(sm.output.npz, npz_bytes(arrays), "stream_head_reference", prov)


run_step(snakemake, main)  # noqa: F821
