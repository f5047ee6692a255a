"""A scattered streamed load, step 4: G = the sum of the takes' Grams of their training rows."""

import numpy as np

from facemotion.ingest.scatter import gather_gram
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    files = [np.load(p) for p in sm.input.grams]
    rows = [int(f["rows"]) for f in files]
    G = gather_gram([f["gram"] for f in files], rows)
    log.info("G from %d takes (%d with training sentences): %d rows", len(files),
             sum(1 for r in rows if r), sum(rows))
    write_artifact(sm.output.npz, npz_bytes({"gram": G, "rows": np.array(sum(rows)),
                                             "labels": files[0]["labels"]}),
                   "stream_gram", prov)


run_step(snakemake, main)  # noqa: F821
