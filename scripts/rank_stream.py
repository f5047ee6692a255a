"""A scattered streamed load's r values (paper Fig. 2): the gathered Gram ranked (pivoted
Cholesky of G = A^T A, the Gram route of QR with column pivoting)."""

import numpy as np

from facemotion.ranking.epsilon_rank import remainder_norms, singular_values
from facemotion.ranking.qr import rank_from_gram
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table


def main(sm, log, prov):
    with np.load(sm.input.gram) as g:
        G, rows, labels = g["gram"], int(g["rows"]), [str(x) for x in g["labels"]]
    ranking = rank_from_gram(G, rows, labels)  # every pivot, as the study ranks
    table = ranking.to_frame(sm.params.r_normalisation)
    table["singular_value"] = singular_values(ranking)
    table["remainder_norm"] = remainder_norms(ranking)
    write_table(table, sm.output.r_values, "r_values", prov)
    log.info("%d rows x %d markers ranked from the gathered Gram; first pivots %s", rows,
             len(labels), ", ".join(ranking.labels_in_order[:5]))


run_step(snakemake, main)  # noqa: F821
