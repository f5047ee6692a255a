"""Atomic writing: every output appears whole or not at all.

A file is written to a temporary name beside its target and renamed onto it, with the mode a
plain ``open`` would give it (the umask), so a killed job or a full disk never leaves a
half-written file under an output's name."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # tables come from pandas; this module itself does not need it
    pass


def current_umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def temp_prefix(path: str | os.PathLike) -> str:
    """Temporary files of an output are named ``.<name>.<random>.tmp<suffix>`` beside it."""
    return f".{Path(path).name}."


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """A temporary path beside ``path``, renamed onto it if the block succeeds.

    The file gets the mode a plain ``open`` would give it (0666 less the umask; ``mkstemp``
    makes 0600, which others on a shared file system could not read). On failure the
    temporary file is removed and an OSError names ``path`` (not the temporary name).
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=temp_prefix(target),
                               suffix=f".tmp{suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, target)
    except OSError as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if e.filename in (None, tmp):
            raise OSError(e.errno, e.strerror, str(target)) from None
        raise
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write to a temporary file beside ``path`` and rename it, so no half-written file is seen."""
    with atomic_path(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
