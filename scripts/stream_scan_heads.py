"""One take of a scattered streamed load, step 1: read in blocks, each of its sentences checked;
their head points and the copy_markers pairs' points."""

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.loading import check_marker_lists
from facemotion.ingest.scatter import heads_arrays, scan_heads
from facemotion.ingest.segments import Segment
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
    sentences = sm.params.take["sentences"]
    heads, rate, pairs = scan_heads(
        take, ds["format"], used, ds["head_markers"],
        sentences=None if sentences is None else [Segment.from_param(s) for s in sentences],
        limits=limits_from_config(sm.params.gaps, sm.params.checks), units=ds["units"],
        subject_prefix=ds["subject_prefix"], max_gib=sm.params.max_gib,
        copy_markers=parse_copy_markers(ds["copy_markers"], "copy_markers"),
        rate=ds.get("rate"))
    prov.inputs = [take]
    arrays = heads_arrays(heads, rate, pairs, sm.params.take["positions"])
    write_artifact(sm.output.npz, npz_bytes(arrays), "stream_heads", prov)


run_step(snakemake, main)  # noqa: F821
