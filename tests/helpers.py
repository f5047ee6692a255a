"""What many tests share: the repository, the shared real data, and stand-ins for Snakemake's
objects (for running scripts and adapters without Snakemake).

``SHARED_DATA`` is ``../shared/data`` beside the repository, or ``FACEMOTION_SHARED_DATA``. CI
always has it, so tests on it run and never skip (the ``shared_data`` fixture fails when it is
missing).
"""

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("FACEMOTION_SHARED_DATA") or REPO.parent / "shared" / "data")
SCHEMAS = REPO / "workflow" / "schemas"


def require_shared_data(root: Path = SHARED_DATA, parts=("animface", "grid")) -> Path:
    """``root`` if it holds the shared data's folders ``parts``; otherwise the test fails
    (never skips) with one line saying where it looked."""
    import pytest

    if not all((root / part).is_dir() for part in parts):
        pytest.fail(f"real data not found at {root} (expected {', '.join(parts)} there); set "
                    "FACEMOTION_SHARED_DATA to the shared data folder")
    return root


class Names(list):
    """A list whose named items are also attributes, like Snakemake's namedlist."""

    def __init__(self, items=(), **named):
        super().__init__(list(items) + list(named.values()))
        self._named = named
        for k, v in named.items():
            setattr(self, k, v)

    def items(self):
        return self._named.items()

    def keys(self):
        return self._named.keys()

    def __getitem__(self, key):
        return self._named[key] if isinstance(key, str) else super().__getitem__(key)
