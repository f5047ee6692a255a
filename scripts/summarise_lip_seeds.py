"""Basu & Pentland's Table 1 over the seeds of the virtual lip talkers: one table of per-seed
cells under both estimator readings."""

import pandas as pd

from facemotion.lips.seeds import aggregate_seeds, direction_counts
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table


def main(sm, log, prov):
    table = aggregate_seeds([pd.read_csv(f, sep="\t") for f in sm.input.tables])
    write_table(table, sm.output.table, "lip_table1_seeds", prov)
    for _, r in direction_counts(table).iterrows():
        log.info("%s, %s, %s: %d of %d seeds with fewer modes better (seeds %s)",
                 r["lip_subject"], r["estimator_reading"], r["view"], r["n_modes_better"],
                 r["n_seeds"], r["seeds_modes_better"] or "none")


run_step(snakemake, main)  # noqa: F821
