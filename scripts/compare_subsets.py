"""How far from optimal is the pivoted-QR choice of k markers? (beyond the paper)"""

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.regions.optimality import subset_optimality
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table


def main(sm, log, prov):
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    table = subset_optimality(train.A, train.labels, k_max=sm.params.k_max)
    write_table(table, sm.output.table, "optimality", prov)


run_step(snakemake, main)  # noqa: F821
