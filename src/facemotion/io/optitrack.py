"""OptiTrack Motive CSV export.

Layout (Motive documentation, "Data Export: CSV"; format versions 1.2x): line 1 holds the
take's settings as name, value pairs (``Format Version``, ``Capture Frame Rate``, ``Export Frame
Rate``, ``Total Exported Frames``, ``Rotation Type``, ``Length Units``, ...); a blank line; then
header rows labelled in their second cell: ``Type`` (``Marker``, ``Rigid Body``, ``Rigid Body
Marker``, ``Bone``, ``Bone Marker``, ...), ``Name``, ``ID`` (and ``Parent`` in newer versions);
a row naming each column's quantity (``Position``, ``Rotation``, ``Marker Quality``, ...); and
the row ``Frame, Time (Seconds), X, Y, Z, ...``. One row per frame follows; an occluded marker
has empty cells.

Only measured markers are read: columns of type ``Marker`` whose quantity is ``Position``.
Rigid bodies and bones (poses) and rigid-body or bone markers (where Motive expects a marker,
not where it was seen) are left out with a log line, as are unlabeled markers (``Unlabeled
1234``), whose identity changes from frame to frame. Units come from ``Length Units``
(the sheet's ``units`` only for a file without it).
"""

from __future__ import annotations

import csv
import logging
import math
import re

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.recording import Recording

log = logging.getLogger("facemotion")
_UNLABELED = re.compile(r"^Unlabeled\s*\d+$", re.IGNORECASE)
_UNITS = {"meters": "m", "meter": "m", "centimeters": "cm", "centimeter": "cm",
          "millimeters": "mm", "millimeter": "mm"}


def _label_row(rows, label: str, stop: int) -> list[str] | None:
    for r in rows[1:stop]:
        if len(r) > 1 and r[1].strip() == label or r and r[0].strip() == label:
            return r
    return None


def read_optitrack_csv(path, units: str | None = None) -> Recording:
    """Read the labelled markers of a Motive CSV export (see the module docstring)."""
    from facemotion.io.base import check_readable, unit_scale

    p = check_readable(path)
    rows = _read_rows(p)
    meta = {rows[0][k].strip(): rows[0][k + 1].strip()
            for k in range(0, len(rows[0]) - 1, 2)}
    axis_at = next((k for k, r in enumerate(rows) if r and r[0].strip() == "Frame"), None)
    if axis_at is None:
        raise InputError(f"{p}: no 'Frame, Time (Seconds), X, Y, Z' header row")
    types = _label_row(rows, "Type", axis_at)
    names = _label_row(rows, "Name", axis_at)
    if types is None or names is None:
        raise InputError(f"{p}: header rows 'Type' and 'Name' not found above line "
                         f"{axis_at + 1}")
    order, columns = marker_columns(p, types, names, rows[axis_at - 1], rows[axis_at])
    rate = _frame_rate(p, meta)
    used, source = _length_units(p, meta, units)
    scale = unit_scale(used, f"{p} ({'Length Units' if source == 'file' else 'sheet units'})")
    values = _frame_values(p, rows[axis_at + 1:], axis_at + 1, meta,
                           [columns[name][a] for name in order for a in "XYZ"])
    xyz = values.reshape(len(values), len(order), 3) * scale
    return Recording(order, xyz, rate, source=str(p), units=used, units_source=source)


def _read_rows(p) -> list[list[str]]:
    """The file's CSV rows; line 1 must start with 'Format Version'."""
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise InputError(f"{p}: cannot read Motive CSV text ({e})") from None
    if not rows or not rows[0] or rows[0][0].strip() != "Format Version":
        first = rows[0][0] if rows and rows[0] else ""
        raise InputError(f"{p}: not a Motive CSV export (line 1 starts with {token(first)}, not "
                         "'Format Version'; export with the header enabled)")
    return rows


def marker_columns(p, types: list[str], names: list[str], quantity: list[str],
                   axes: list[str]) -> tuple[list[str], dict[str, dict[str, int]]]:
    """The labelled markers' names in column order and each one's X, Y, Z position columns;
    the other columns left out with one log line."""

    def cell(row, j):
        return row[j].strip() if j < len(row) else ""

    columns: dict[str, dict[str, int]] = {}
    order: list[str] = []
    dropped: dict[str, set[str]] = {}
    for j in range(2, len(axes)):
        kind, name, what, axis = cell(types, j), cell(names, j), cell(quantity, j), cell(axes, j)
        if not kind and not name:
            continue  # e.g. a TimeCode column
        if kind != "Marker" or what != "Position" or axis not in ("X", "Y", "Z"):
            dropped.setdefault(kind.lower() or "unnamed", set()).add(name)
            continue
        if _UNLABELED.match(name):
            dropped.setdefault("unlabeled marker", set()).add(name)
            continue
        if not name:
            raise InputError(f"{p}: marker column {j + 1} has no name")
        if name not in columns:
            columns[name] = {}
            order.append(name)
        if axis in columns[name]:
            raise InputError(f"{p}: marker {name!r} has two {axis} position columns")
        columns[name][axis] = j
    for name in order:
        lacking = [a for a in "XYZ" if a not in columns[name]]
        if lacking:
            raise InputError(f"{p}: marker {name!r} has no {', '.join(lacking)} position "
                             "column")
    if dropped:
        log.info("%s: left out %s", p, "; ".join(
            f"{len(v)} {k}{'s' if len(v) != 1 else ''} ({', '.join(sorted(v)[:6])}"
            f"{', ...' if len(v) > 6 else ''})" for k, v in dropped.items()))
    if not order:
        raise InputError(f"{p}: no labelled marker positions (columns of type 'Marker'); "
                         "export with Markers enabled and label the markers")
    return order, columns


def _frame_rate(p, meta: dict) -> float:
    rate_text = meta.get("Export Frame Rate") or meta.get("Capture Frame Rate")
    try:
        rate = float(rate_text)
    except (TypeError, ValueError):
        raise InputError(f"{p}: no numeric Export/Capture Frame Rate in line 1 "
                         f"(got {token(rate_text)})") from None
    if not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{p}: frame rate must be positive, got {token(rate_text)}")
    return rate


def _length_units(p, meta: dict, units: str | None) -> tuple[str, str]:
    """The length unit and where it came from ('file': Length Units, or 'sheet')."""
    length = meta.get("Length Units")
    if length:
        if length.lower() not in _UNITS:
            raise InputError(f"{p}: unknown Length Units {token(length)} (Meters, Centimeters, "
                             "Millimeters)")
        return _UNITS[length.lower()], "file"
    if units is not None:
        return units, "sheet"
    raise InputError(f"{p}: line 1 has no Length Units; give the units in the subject sheet")


def _frame_values(p, rows: list[list[str]], first_line: int, meta: dict, idx: list[int]
                  ) -> np.ndarray:
    """(frames, len(idx)) values of the non-blank data rows in columns ``idx``; an empty cell
    is NaN (an occluded marker)."""
    data = [(k + 1, r) for k, r in enumerate(rows, start=first_line) if any(c.strip() for c in r)]
    if not data:
        raise InputError(f"{p}: Motive CSV has no frames")
    total = meta.get("Total Exported Frames")
    if total and total.isdigit() and int(total) != len(data):
        raise InputError(f"{p}: Total Exported Frames is {total} but there are {len(data)} "
                         "data rows")
    values = np.empty((len(data), len(idx)))
    for r, (line_no, row) in enumerate(data):
        try:
            values[r] = [float(row[j]) if j < len(row) and row[j].strip() else math.nan
                         for j in idx]
        except ValueError:
            bad = next(j for j in idx if j < len(row) and row[j].strip()
                       and not _is_float(row[j]))
            raise InputError(f"{p}, line {line_no}: non-numeric value {token(row[bad])} in "
                             f"column {bad + 1}") from None
    return values


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
