"""Wide CSV: ``time`` (s), then ``<label>_x``, ``<label>_y``, ``<label>_z`` columns."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io import base
from facemotion.io.atomic import atomic_path
from facemotion.io.base import (
    check_last_line_ended,
    check_readable,
    fast_numeric_lines,
    format_coordinate,
    head_lines,
    is_float,
    unit_scale,
)
from facemotion.io.recording import Recording


def _csv_columns(p: Path, cols: list[str], line: int):
    """Marker labels and the column of each axis from a wide CSV's header (InputError else)."""
    if cols[0] != "time":
        raise InputError(f"{p}: line {line}: first column must be 'time', got "
                         f"{token(cols[0])}")
    labels: list[str] = []
    axes: dict[str, dict[str, int]] = {}
    for j, col in enumerate(cols[1:], start=1):
        label, sep, axis = col.rpartition("_")
        if not sep or not label or axis not in ("x", "y", "z"):
            raise InputError(f"{p}: column {j + 1} {token(col)} is not of the form "
                             "<label>_x/_y/_z")
        if label not in axes:
            labels.append(label)
            axes[label] = {}
        if axis in axes[label]:
            raise InputError(f"{p}: column {j + 1} {token(col)} appears twice")
        axes[label][axis] = j
    if not labels:
        raise InputError(f"{p}: no marker columns after 'time'")
    for label in labels:
        lacking = [a for a in "xyz" if a not in axes[label]]
        if lacking:
            raise InputError(f"{p}: marker {token(label)} has no column(s) "
                             + ", ".join(token(f"{label}_{a}") for a in lacking))
    return labels, axes


def _read_csv_fast(p: Path):
    """The CSV reader's fast path: (columns, labels, axes, values, line numbers) or None."""
    try:
        with open(p, "rb") as fh:
            first = fh.readline()
            offset = fh.tell()
        header = first.decode("utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    if not header.endswith("\n") or '"' in header or not header.strip() or "\x00" in header:
        return None
    cols = [c.strip() for c in header.rstrip("\r\n").split(",")]
    try:
        labels, axes = _csv_columns(p, cols, 1)
    except InputError:
        return None
    got = fast_numeric_lines(p, offset, 2, len(cols), b",")
    if got is None or got[0].shape[0] < 2:
        return None
    values, numbers = got
    return cols, labels, axes, values, np.concatenate([[1], numbers])


def _read_csv_exact(p: Path):
    """The exact CSV path: (columns, labels, axes, values, line numbers) or InputError."""
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read as CSV text ({type(e).__name__})") from None
    lines = text.splitlines(keepends=True) if "\x00" not in text else None
    if lines is None:
        raise InputError(f"{p}: cannot read as CSV text (binary content)")
    check_last_line_ended(p, lines)
    try:
        table = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as e:
        raise InputError(f"{p}: cannot read as CSV ({str(e).splitlines()[0][:80]})") from None
    # a blank line is skipped; a line of commas is a frame with empty fields
    numbers = [i + 1 for i, r in enumerate(table) if len(r) > 1 or (r and r[0].strip())]
    table = [r for r in table if len(r) > 1 or (r and r[0].strip())]
    if not table:
        raise InputError(f"{p}: CSV file is empty")
    cols = [str(c).strip() for c in table[0]]
    labels, axes = _csv_columns(p, cols, numbers[0])
    for r, n in zip(table[1:], numbers[1:], strict=True):
        if len(r) != len(cols):
            raise InputError(f"{p}: line {n} has {len(r)} fields but the header has "
                             f"{len(cols)}; a missing sample must be an empty field")
    if len(table) < 3:
        raise InputError(f"{p}: need at least 2 frames to get the rate from 'time'")
    raw = np.array(table[1:], dtype=object)
    raw = np.where(np.char.strip(raw.astype(str)) == "", "nan", raw)
    try:
        values = raw.astype(float)
    except ValueError:
        for i, row in enumerate(raw):
            for j, v in enumerate(row):
                if not is_float(v):
                    raise InputError(f"{p}: non-numeric value {token(v)} in line "
                                     f"{numbers[i + 1]} column {j + 1}") from None
        raise
    return cols, labels, axes, values, numbers


def read_csv(path, units: str | None = None) -> Recording:
    """Read a wide CSV: ``time`` (s), then ``<label>_x``, ``<label>_y``, ``<label>_z`` columns.

    The rate is 1 / (the time step), which must be uniform (within 1 % of the mean step).
    Units are mm unless ``units`` (the sheet's) is given: a CSV does not state its units.
    Empty cells are missing samples; every row must have a cell for every column, and the
    last line must end with a line end (a CSV has no frame count, so a cut file is caught
    only when the cut falls inside a line).

    Regular files are parsed at C-parser speed (:func:`fast_numeric_lines`); anything else
    goes through the exact reader (Python's csv module), which gives the errors.
    """
    p = check_readable(path)
    fast = _read_csv_fast(p) if base.FAST_TEXT else None
    if fast is not None:
        cols, labels, axes, values, numbers = fast
    else:
        cols, labels, axes, values, numbers = _read_csv_exact(p)
    t = values[:, 0]
    if not np.isfinite(t).all():
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"{p}: line {numbers[i + 1]}: 'time' is empty or not finite")
    dt = np.diff(t)
    step = (t[-1] - t[0]) / (t.size - 1)
    if (dt <= 0).any():
        k = int(np.flatnonzero(dt <= 0)[0])
        raise InputError(f"{p}: line {numbers[k + 2]}: 'time' {t[k + 1]:.6g} s does not "
                         f"increase from {t[k]:.6g} s")
    if np.max(np.abs(dt - step)) > 0.01 * step:
        k = int(np.argmax(np.abs(dt - step)))
        raise InputError(f"{p}: column 'time' is not uniformly sampled (step {dt[k]:.6g} s "
                         f"at line {numbers[k + 2]} vs mean step {step:.6g} s)")
    rate = round(1.0 / step, 3)
    if units is not None:
        used, source = units, "sheet"
    else:
        used, source = "mm", "default"
    scale = unit_scale(used, f"{p} (sheet units)")
    idx = [axes[label][a] for label in labels for a in "xyz"]
    xyz = values[:, idx].reshape(t.size, len(labels), 3) * scale
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def write_csv(path, rec: Recording) -> None:
    """Write ``rec`` as a wide CSV (time in s, coordinates in mm, missing samples empty)."""
    header = ["time"] + [f"{lab}_{a}" for lab in rec.labels for a in "xyz"]
    for col in header:
        if "," in col or '"' in col:
            raise InputError(f"{rec.source or 'recording'}: marker label in column {col!r} "
                             "cannot be written to CSV")
    flat = rec.points.reshape(rec.n_frames, 3 * rec.n_markers)
    out = [",".join(header)]
    for f in range(rec.n_frames):
        out.append(f"{f / rec.rate:.9g}," + ",".join(format_coordinate(x) for x in flat[f]))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")


def read_csv_labels(path) -> list[str]:
    """A wide CSV's marker labels from its header line alone."""
    _, (first,) = head_lines(path, 1)
    cols = next(csv.reader([first]), [])
    labels: list[str] = []
    for c in cols[1:]:
        lab = c.strip().rpartition("_")[0]
        if lab and lab not in labels:
            labels.append(lab)
    return labels
