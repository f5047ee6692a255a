"""results/<study>/manifest.tsv: every output with its checksum, schema version and sidecar."""

from facemotion.manifest import build_manifest
from facemotion.provenance import atomic_write_bytes, table_bytes
from facemotion.snakemake_adapter import run_step


def main(sm, log, prov):
    root = sm.params.root
    table = build_manifest(root, exclude=(f"{root}/logs", f"{root}/manifest"))
    log.info("%d outputs in the manifest", len(table))
    # The manifest is the index of the sidecars, so it has none of its own.
    atomic_write_bytes(sm.output.manifest, table_bytes(table))


run_step(snakemake, main)  # noqa: F821
