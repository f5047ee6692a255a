"""The results manifest: every output with its checksum, schema and provenance sidecar."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from facemotion.errors import InputError
from facemotion.provenance import SIDECAR_SUFFIX, sha256_file


def build_manifest(results_dir: str | Path, exclude: tuple[str, ...] = ()) -> pd.DataFrame:
    """One row per output listed by a sidecar under ``results_dir`` (sorted by path).

    The checksum is recomputed from the file on disk and compared with the one its sidecar
    recorded; a mismatch means the file changed after it was written, which is an error.
    """
    results_dir = Path(results_dir)
    rows = []
    for side in sorted(results_dir.rglob(f"*{SIDECAR_SUFFIX}")):
        if any(str(side).startswith(e) for e in exclude):
            continue
        meta = json.loads(side.read_text())
        for out in meta.get("outputs", []):
            path = Path(out["path"])
            if not path.is_file():
                raise InputError(f"{side}: lists {path}, which does not exist")
            digest = sha256_file(path)
            if digest != out["sha256"]:
                raise InputError(f"{path}: checksum differs from its sidecar {side} "
                                 "(file changed after it was written)")
            rows.append({"path": str(path), "sha256": digest, "bytes": path.stat().st_size,
                         "schema_id": meta["schema_id"],
                         "schema_version": meta["schema_version"],
                         "step": meta.get("step", ""), "sidecar": str(side),
                         "git_commit": meta.get("git", {}).get("commit", "")})
    return pd.DataFrame(rows, columns=["path", "sha256", "bytes", "schema_id",
                                       "schema_version", "step", "sidecar", "git_commit"])
