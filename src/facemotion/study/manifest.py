"""The results manifest: every output of the current workflow, with its checksum, schema and
provenance sidecar.

The manifest lists what the workflow as it stands produced, not whatever lies under
``results/``: it starts from the workflow's targets and follows the sidecars. A sidecar names
every output of its job (``job_outputs``) and the inputs it read, so the closure is: the
targets' sidecars, the sidecars of every other output of the same jobs, and, for every input
under the results folder, the sidecar that lists it as an output (recursively). Outputs of
subjects no longer in the sheet, or of settings no longer used, are left out although they are
still on disk. A sidecar that cannot be read is an error naming it.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING

from facemotion.errors import InputError
from facemotion.study.outputs import SIDECAR_SUFFIX
from facemotion.study.provenance import sha256_file, sidecar_path

if TYPE_CHECKING:
    import pandas as pd

COLUMNS = ["path", "sha256", "bytes", "schema_id", "schema_version", "step", "sidecar",
           "git_commit"]


def read_sidecar(side: Path) -> dict:
    """A sidecar's content; InputError naming the file if it is not a valid sidecar."""
    try:
        meta = json.loads(side.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"{side}: not a valid sidecar ({type(e).__name__}: "
                         f"{str(e).splitlines()[0][:80]})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("outputs"), list) \
            or any(not isinstance(o, dict) or "path" not in o or "sha256" not in o
                   for o in meta["outputs"]) or "schema_id" not in meta:
        raise InputError(f"{side}: not a valid sidecar (no schema_id or outputs list)")
    return meta


def _sidecar_listing(path: Path, cache: dict) -> Path | None:
    """The sidecar that lists ``path`` as an output: its own, or one in its folder."""
    own = sidecar_path(path)
    candidates = [own] + sorted(p for p in path.parent.glob(f"*{SIDECAR_SUFFIX}") if p != own)
    for side in candidates:
        if not side.is_file():
            continue
        if side not in cache:
            cache[side] = read_sidecar(side)
        if any(Path(o["path"]) == path for o in cache[side]["outputs"]):
            return side
    return None


def build_manifest(results_dir: str | Path, targets) -> pd.DataFrame:
    """One row per output of the jobs that made ``targets`` and their upstream jobs under
    ``results_dir`` (sorted by path). Checksums are recomputed and compared with the
    sidecars'; a mismatch (a file changed after it was written) is an error."""
    import pandas as pd

    return pd.DataFrame(manifest_rows(results_dir, targets), columns=COLUMNS)


def manifest_tsv(rows: list[dict]) -> bytes:
    """The manifest's TSV (as ``provenance.table_bytes`` writes a table: tab-separated, no
    index, Unix newlines), without pandas: the manifest job is the study's last."""
    buf = io.StringIO()
    writer = csv.writer(buf, delimiter="\t", lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows([row[c] for c in COLUMNS] for row in rows)
    return buf.getvalue().encode()


def manifest_rows(results_dir: str | Path, targets) -> list[dict]:
    """The rows of :func:`build_manifest`, as dicts with the keys ``COLUMNS``."""
    results_dir = Path(results_dir)
    cache: dict[Path, dict] = {}
    todo = []
    for t in targets:
        side = _sidecar_listing(Path(t), cache)
        if side is None:
            raise InputError(f"{t}: no sidecar lists this output")
        todo.append(side)
    seen: set[Path] = set()
    while todo:
        side = todo.pop()
        if side in seen:
            continue
        seen.add(side)
        meta = cache.get(side) or read_sidecar(side)
        cache[side] = meta
        for other in meta.get("job_outputs", []):
            o = Path(other)
            if o.name.endswith(SIDECAR_SUFFIX) or not o.is_file():
                continue
            s = _sidecar_listing(o, cache)
            if s is not None:
                todo.append(s)
        for inp in meta.get("inputs", []):
            p = Path(inp.get("path", ""))
            if p.is_file() and results_dir in p.parents:
                s = _sidecar_listing(p, cache)
                if s is not None:
                    todo.append(s)
    rows = []
    for side in sorted(seen):
        meta = cache[side]
        for out in meta["outputs"]:
            path = Path(out["path"])
            if not path.is_file():
                raise InputError(f"{side}: lists {path}, which does not exist")
            digest = sha256_file(path)
            if digest != out["sha256"]:
                raise InputError(f"{path}: checksum differs from its sidecar {side} "
                                 "(file changed after it was written)")
            rows.append({"path": str(path), "sha256": digest, "bytes": path.stat().st_size,
                         "schema_id": meta["schema_id"],
                         "schema_version": meta.get("schema_version", ""),
                         "step": meta.get("step", ""), "sidecar": str(side),
                         "git_commit": meta.get("git", {}).get("commit", "")})
    first = {}
    for row in rows:  # the first row of each path, then sorted by path
        first.setdefault(row["path"], row)
    return [first[p] for p in sorted(first)]
