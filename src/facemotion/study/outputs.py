"""Each rule's outputs, named one way: a file, its other figure formats, and its sidecar.

A rule declares its outputs with these helpers (``output: **table("rank", path), ...``), and
its script finds them by the same key, so no rule spells out a sidecar or a figure's other
formats by hand:

- :func:`table` and :func:`tables`: ``{key: path, key_meta: sidecar}``;
- :func:`figure`: ``{key: PNG, key_more: [PDF, SVG as figures.formats asks], key_meta:
  sidecar}``, the PNG wrapped for the report when the rule says how;
- :func:`artifact`: any other file with a sidecar (an npz, an animation);
- :func:`figure_files`: a figure's files from a job's outputs, PNG first.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable

from facemotion.plots.save import figure_paths

#: Every table, figure and other output has a sidecar of this suffix beside it.
SIDECAR_SUFFIX = ".meta.json"
META = "_meta"
MORE = "_more"


def sidecar(path: str | os.PathLike) -> str:
    """``results/x/r_values.tsv`` -> ``results/x/r_values.meta.json`` (for a figure, the
    sidecar of its PNG and other formats alike)."""
    p = str(path)
    stem, _ = os.path.splitext(p)
    return stem + SIDECAR_SUFFIX


def table(key: str, path: str) -> dict[str, str]:
    """A table (TSV) and its sidecar, as ``{key: path, key_meta: sidecar}``."""
    return {key: path, key + META: sidecar(path)}


def tables(directory: str, *names: str) -> dict[str, str]:
    """Tables ``directory/<name>.tsv`` named by their stems, each with its sidecar."""
    out: dict[str, str] = {}
    for name in names:
        out.update(table(name, f"{directory}/{name}.tsv"))
    return out


def artifact(key: str, path: str) -> dict[str, str]:
    """Any other output (an npz, an animation, a page) with its sidecar."""
    return {key: path, key + META: sidecar(path)}


def figure(key: str, stem: str, formats: Iterable[str],
           wrap: Callable[[str], object] | None = None) -> dict[str, object]:
    """A figure ``stem.png`` (wrapped by ``wrap``, e.g. Snakemake's ``report``), its other
    formats (the ``figures.formats`` setting) as ``key_more`` and its sidecar."""
    png, *more = figure_paths(stem, formats)
    return {key: png if wrap is None else wrap(png), key + MORE: more,
            key + META: sidecar(png)}


def figure_files(output, key: str) -> list[str]:
    """A figure's files from a job's named outputs (see :func:`figure`): PNG first."""
    more = key + MORE
    extra = list(output[more]) if more in output.keys() else []
    return [str(output[key]), *map(str, extra)]


def _under(path: str, folder: str) -> bool:
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def check_inside_study(paths: Iterable[str | os.PathLike], root: str | os.PathLike = ".",
                       what: str = "output") -> None:
    """Refuse, before anything is written, a path that would place a file outside the study
    root: an absolute path elsewhere, ``..`` leading out, an empty name, or a symbolic link
    inside the study's results folder (``results/<study>/...``) that leads out of it.

    The results folder itself (or ``results/``) may be a link, e.g. to a scratch disk: where
    the study's results live is the user's choice; a link below it would let one output land
    anywhere."""
    from facemotion.errors import InputError

    base = os.path.abspath(root)
    for p in paths:
        text = os.fspath(p)
        full = os.path.normpath(os.path.join(base, text))
        names = text.replace(os.sep, "/").strip("/").split("/")
        if any(not name.strip() for name in names):
            raise InputError(f"{what} path {text!r}: an empty name")
        if not _under(full, base) or full == base:
            raise InputError(f"{what} path {text}: outside the study root {base} (a name "
                             "with '..' or an absolute path); nothing was written")
        parts = os.path.relpath(full, base).split(os.sep)
        top = os.path.join(base, *parts[:2]) if parts[0] == "results" and len(parts) > 2 \
            else base
        allowed = os.path.realpath(top)
        if not _under(os.path.realpath(full), allowed):
            raise InputError(f"{what} path {text}: a symbolic link leads it to "
                             f"{os.path.realpath(full)}, outside {allowed}; nothing was "
                             "written")
