"""One take of a scattered streamed load, step 3: its sentences' rows of A on disk, and the Gram of
its training rows."""

import numpy as np

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.scatter import TakePart, load_take
from facemotion.ingest.segments import Segment
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import sidecar_for_existing, write_artifact
from facemotion.study.settings import limits_from_config


def main(sm, log, prov):
    ds, take = sm.params.take["ds"], sm.params.take["recording"]
    log.info("%s: streamed, memory.max_gib = %g", take, sm.params.max_gib)
    ref = np.load(sm.input.reference)
    gaps = sm.params.gaps
    sentences = sm.params.take["sentences"]
    plan = TakePart(take, None if sentences is None else [Segment.from_param(x) for x in sentences],
                    list(sm.params.take["roles"]), list(sm.params.take["positions"]))
    part = load_take(
        plan, ds["format"], sm.output.npz,
        head_reference=ref["reference"] if "reference" in ref else None,
        units=ds["units"], head_markers=ds["head_markers"],
        exclude_markers=ds["exclude_markers"], include_markers=ds["include_markers"],
        max_interp_s=gaps["max_interp_s"], long_gaps=gaps["long_gaps"],
        neutral=sm.params.neutral, limits=limits_from_config(gaps, sm.params.checks),
        subject_prefix=ds["subject_prefix"],
        copy_markers=parse_copy_markers(ds["copy_markers"], "copy_markers"),
        copy_medians=ref["copy_medians"] if "copy_medians" in ref else None,
        max_gib=sm.params.max_gib, rate=ds.get("rate"))
    prov.inputs = [take, sm.input.reference]
    log.info("%s: %d sentence(s), %d training rows x %d markers", take, len(plan.roles),
             part.train_rows, len(part.labels))
    sidecar_for_existing(sm.output.npz, "displacements", prov)
    write_artifact(sm.output.gram, npz_bytes({"gram": part.gram,
                                              "rows": np.array(part.train_rows),
                                              "labels": np.array(part.labels)}),
                   "stream_gram", prov)


run_step(snakemake, main)  # noqa: F821
