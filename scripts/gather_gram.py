"""A scattered streamed load, step 4: G = sum of the training takes' Grams."""

import numpy as np

from facemotion.ingest.scatter import gather_gram
from facemotion.io.npz import npz_bytes
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    roles = list(sm.params.roles)
    files = [np.load(p) for p in sm.input.grams]
    G = gather_gram([f["gram"] for f in files], roles)
    rows = sum(int(f["rows"]) for f, r in zip(files, roles, strict=True) if r == "train")
    log.info("G from %d training takes of %d: %d rows", roles.count("train"), len(roles), rows)
    write_artifact(sm.output.npz, npz_bytes({"gram": G, "rows": np.array(rows),
                                             "labels": files[0]["labels"]}),
                   "stream_gram", prov)


run_step(snakemake, main)  # noqa: F821
