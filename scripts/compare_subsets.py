"""How far from optimal is the pivoted-QR choice of k markers? (beyond the paper)"""

from facemotion.displacements import load_displacements, split_roles
from facemotion.provenance import write_table
from facemotion.snakemake_adapter import run_per_dataset
from facemotion.subset_optimality import subset_optimality


def main(sm, log, prov):
    train, _ = split_roles(load_displacements(sm.input.npz), sm.input.sentences)
    table = subset_optimality(train.A, train.labels, k_max=sm.params.k_max)
    write_table(table, sm.output.table, "optimality", prov)


run_per_dataset(snakemake, main)  # noqa: F821
