"""results/<study>/manifest.tsv: every output of the current workflow with its checksum, schema
version and sidecar (starting from the workflow's targets, not from what lies in results/)."""

from facemotion.io.atomic import atomic_write_bytes
from facemotion.study.adapter import run_step
from facemotion.study.manifest import manifest_rows, manifest_tsv


def main(sm, log, prov):
    root = sm.params.root
    rows = manifest_rows(root, targets=list(sm.input.outputs))
    log.info("%d outputs in the manifest", len(rows))
    # The manifest is the index of the sidecars, so it has none of its own.
    atomic_write_bytes(sm.output.manifest, manifest_tsv(rows))


run_step(snakemake, main)  # noqa: F821
