"""One point of a parameter sweep on one dataset."""

import pandas as pd

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table
from facemotion.study.sweeps import evaluate_point


def main(sm, log, prov):
    train, held = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    row = evaluate_point(train, held, dict(sm.params.point), method=sm.params.method,
                         settle_tolerance=sm.params.settle_tolerance,
                         r_normalisation=sm.params.r_normalisation)
    row = {"sweep": sm.wildcards.sweep, "dataset": sm.params.label,
           "point": sm.wildcards.point, **row}
    log.info("%s", row)
    write_table(pd.DataFrame([row]), sm.output.table, "summary", prov)


run_step(snakemake, main)  # noqa: F821
