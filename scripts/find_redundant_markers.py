"""Find markers that copy others, over the whole recording or only during a filled gap."""

from facemotion.ingest.displacement_file import load_displacements
from facemotion.regions.redundancy import find_redundant_markers, longest
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_table


def main(sm, log, prov):
    d = load_displacements(sm.input.npz)
    table = find_redundant_markers(d.A, d.labels, d.row_sentence, d.rate,
                                   noise_mm=sm.params.noise_mm,
                                   min_duration_s=sm.params.min_copy_s,
                                   sentence_names=d.sentences,
                                   fill_mask=d.fill_mask)
    log.info("%d suspect interval(s); the %d longest in redundancy_top.tsv", len(table),
             min(len(table), sm.params.top_n))
    write_table(table, sm.output.redundancy, "redundancy", prov)
    write_table(longest(table, sm.params.top_n), sm.output.redundancy_top, "redundancy", prov)


run_step(snakemake, main)  # noqa: F821
