"""A scattered streamed load's held-out error against k (paper Fig. 10): the held-out takes'
parts of A read in blocks, never whole."""

import numpy as np

from facemotion.ingest.scatter import heldout_blocks
from facemotion.ranking.qr import rank_from_gram
from facemotion.regions.streamed_curve import streamed_error_curve
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table


def main(sm, log, prov):
    with np.load(sm.input.gram) as g:
        G, rows, labels = g["gram"], int(g["rows"]), [str(x) for x in g["labels"]]
    ranking = rank_from_gram(G, rows, labels)  # every pivot, as the study ranks
    parts = list(zip(sm.input.heldout, sm.params.heldout, strict=True))
    curve = streamed_error_curve(ranking, heldout_blocks(parts), labels, k_max=sm.params.k_max)
    write_table(curve, sm.output.curve, "error_curve", prov)
    log.info("error curve for k = 1..%d over %d held-out takes, read in blocks", len(curve) - 1,
             len(parts))


run_step(snakemake, main)  # noqa: F821
