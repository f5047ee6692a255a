"""One take of a scattered streamed load, step 1: read in blocks, checked, its head points (and
the copy_markers pairs' points)."""

import numpy as np

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.loading import check_marker_lists
from facemotion.ingest.scatter import scan_heads
from facemotion.io.npz import npz_bytes
from facemotion.io.registry import read_labels
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact
from facemotion.study.settings import limits_from_config


def main(sm, log, prov):
    ds, take = sm.params.take["ds"], sm.params.take["recording"]
    log.info("%s: streamed, memory.max_gib = %g", take, sm.params.max_gib)
    labels = read_labels(take, ds["format"], ds["subject_prefix"])
    _, used = check_marker_lists(labels, take, ds["head_markers"], ds["exclude_markers"],
                                 ds["include_markers"])
    pairs = parse_copy_markers(ds["copy_markers"], "copy_markers")
    head, rate, pair_points = scan_heads(
        take, ds["format"], used, ds["head_markers"],
        limits=limits_from_config(sm.params.gaps, sm.params.checks), units=ds["units"],
        subject_prefix=ds["subject_prefix"], max_gib=sm.params.max_gib, copy_markers=pairs)
    prov.inputs = [take]
    arrays = {"rate": np.array(rate)}
    if head is not None:
        arrays["head"] = head
    for j, pts in enumerate(pair_points):
        arrays[f"pair{j}"] = pts
    write_artifact(sm.output.npz, npz_bytes(arrays), "stream_heads", prov)


run_step(snakemake, main)  # noqa: F821
