"""Content fingerprints of a study's input files, so that reruns follow content, not clocks.

Snakemake reruns a job when an input is newer than its outputs. A take replaced by an older
copy (``cp -p``, ``rsync -t``, ``touch -d``, a restored backup) is not newer, and the study
would keep describing the old take. The loading rule therefore carries, as a parameter, the
SHA-256 of each recording, TextGrid and interval table it reads: Snakemake's ``params`` rerun
trigger (on by default) reruns it, and everything downstream, when a digest changes, and says
so ("Params have changed since last execution", with the file's name and digest).

Hashing every input at every invocation would read every take each time; a cache in the
study's results folder keeps each file's digest while its device, inode, size, modification
time and change time stay the same. ``cp -p``, ``rsync -t`` and ``touch -d`` all change the
change time (``ctime``, which no user call can set back), so no replacement goes unseen.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from facemotion.io.atomic import atomic_write_bytes

#: How much of each digest a parameter shows (64 bits: a change is never missed by chance
#: in practice, and the rerun reason stays one readable line per file).
SHOWN_HEX = 16
CACHE_VERSION = 1


def _stat_key(st: os.stat_result) -> list[int]:
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def sha256_of(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes, read in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


class FingerprintCache:
    """Digests of files by absolute path, valid while (device, inode, size, mtime, ctime)
    stay the same; kept in a JSON file (``path``) that :meth:`save` writes when it changed.

    A file whose digest differs from the cached one is remembered in :attr:`changed` (its
    path, old and new digest), so the workflow can say which input's content changed.
    """

    def __init__(self, path: str | os.PathLike | None):
        self.path = Path(path) if path is not None else None
        self.entries: dict[str, list] = {}
        self.changed: list[tuple[str, str, str]] = []
        self._dirty = False
        if self.path is not None and self.path.is_file():
            try:
                data = json.loads(self.path.read_text())
                if data.get("version") == CACHE_VERSION and isinstance(data.get("files"), dict):
                    self.entries = data["files"]
            except (OSError, ValueError, AttributeError):
                self.entries = {}  # a damaged cache is only a slower run: hash again

    def digest(self, path: str | os.PathLike) -> str:
        """The file's SHA-256, from the cache when its identity and times are unchanged."""
        full = os.path.abspath(path)
        key = _stat_key(os.stat(full))
        entry = self.entries.get(full)
        if isinstance(entry, list) and len(entry) == 2 and entry[0] == key:
            return entry[1]
        value = sha256_of(full)
        if isinstance(entry, list) and len(entry) == 2 and entry[1] != value:
            self.changed.append((full, entry[1], value))
        self.entries[full] = [key, value]
        self._dirty = True
        return value

    def save(self) -> None:
        """Write the cache if a digest was added or renewed (atomically; a cache that cannot
        be written is skipped: it only saves reading the files again)."""
        if self.path is None or not self._dirty:
            return
        text = json.dumps({"version": CACHE_VERSION, "files": self.entries}, sort_keys=True)
        try:
            atomic_write_bytes(self.path, (text + "\n").encode())
            self._dirty = False
        except OSError:
            pass  # a read-only or full results folder: the run itself says so


def fingerprint(files: Iterable[str], cache: FingerprintCache,
                names: Mapping[str, str] | None = None) -> list[str]:
    """``["<name> sha256:<first 16 hex>", ...]`` for ``files`` in their order, each named by
    ``names`` (the path as the study records it) or else by its path; a file listed twice
    appears once."""
    out = []
    for f in dict.fromkeys(map(str, files)):
        shown = (names or {}).get(f, f)
        out.append(f"{shown} sha256:{cache.digest(f)[:SHOWN_HEX]}")
    return out
