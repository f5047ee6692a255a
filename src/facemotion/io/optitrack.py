"""OptiTrack Motive CSV export.

Layout (Motive documentation, "Data Export: CSV"; format versions 1.21 to 3.x): line 1 holds
the take's settings as name, value pairs (``Format Version``, ``Capture Frame Rate``, ``Export
Frame Rate``, ``Total Exported Frames``, ``Rotation Type``, ``Length Units``, ...); a blank line;
then header rows: the type of each column's asset (``Marker``, ``Rigid Body``, ``Rigid Body
Marker``, ``Bone``, ``Bone Marker``, ...), its name, its ID (and its parent in newer versions),
labelled ``Type``, ``Name``, ``ID``, ``Parent`` in their second cell since format 1.22 and
unlabelled, in that order, in 1.21; a row naming each column's quantity (``Position``,
``Rotation``, ``Marker Quality``, ...); and the row ``Frame, Time (Seconds), X, Y, Z, ...``
(``Frame, Time`` in 1.21). One row per frame follows; an occluded marker has empty cells.

Only measured markers are read: columns of type ``Marker`` whose quantity is ``Position``
(a rigid body's labelled markers, ``Rigid Body 1:Marker1``, are such markers). Rigid bodies
and bones (poses) and rigid-body or bone markers (where Motive expects a marker, not where it
was seen) are left out with a log line, as are unlabeled markers (``Unlabeled 1234``,
``Unlabeled:108`` in 1.21), whose identity changes from frame to frame. Units come from
``Length Units`` (the sheet's ``units`` only for a file without it).

Every data row has the axis row's number of fields; the Frame column steps by 1 and the Time
column lies on the grid of the export frame rate (Motive rounds it, in some versions to the
millisecond); the rows are Total Exported Frames; the last row ends with a line end. Each
is checked by :func:`check_motive_block`, which also runs on a block of rows.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import re

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.checks import (
    check_field_counts,
    check_frame_count,
    check_frame_numbers,
    check_time_grid,
)
from facemotion.io.recording import Recording

log = logging.getLogger("facemotion")
_UNLABELED = re.compile(r"^Unlabeled[\s:]*\d+$", re.IGNORECASE)
_HEADER_LABELS = ("Type", "Name", "ID", "Parent")
#: Motive writes Time with 6 decimals, some versions rounded to the millisecond.
MOTIVE_TIME_ROUNDING_S = 0.0005
_UNITS = {"meters": "m", "meter": "m", "centimeters": "cm", "centimeter": "cm",
          "millimeters": "mm", "millimeter": "mm"}


def header_rows(p, rows: list[list[str]], axis_at: int) -> tuple[list[str], list[str]]:
    """The Type and Name rows above the quantity row: labelled in their second cell (format
    1.22 and later), else the first two of the four unlabelled rows (1.21)."""
    above = [r for r in rows[1:axis_at - 1] if any(c.strip() for c in r)]
    labelled = {r[1].strip(): r for r in above if len(r) > 1 and r[1].strip() in _HEADER_LABELS}
    labelled.update({r[0].strip(): r for r in above if r and r[0].strip() in _HEADER_LABELS})
    if "Type" in labelled and "Name" in labelled:
        return labelled["Type"], labelled["Name"]
    if not labelled and len(above) == 3:  # 1.21: type, name, ID rows, no labels
        return above[0], above[1]
    raise InputError(f"{p}: header rows 'Type' and 'Name' not found above line {axis_at + 1} "
                     f"({len(above)} header rows, labelled {sorted(labelled) or 'none'})")


def read_optitrack_csv(path, units: str | None = None) -> Recording:
    """Read the labelled markers of a Motive CSV export (see the module docstring)."""
    from facemotion.io.base import check_readable, unit_scale

    p = check_readable(path)
    rows = _read_rows(p)
    meta = {rows[0][k].strip(): rows[0][k + 1].strip()
            for k in range(0, len(rows[0]) - 1, 2)}
    axis_at = next((k for k, r in enumerate(rows) if r and r[0].strip() == "Frame"), None)
    if axis_at is None or axis_at < 2:
        raise InputError(f"{p}: no 'Frame, Time (Seconds), X, Y, Z' header row")
    axes = rows[axis_at]
    if len(axes) < 2 or not axes[1].strip().startswith("Time"):
        raise InputError(f"{p}: line {axis_at + 1}: the second column must be 'Time'")
    types, names = header_rows(p, rows, axis_at)
    order, columns = marker_columns(p, types, names, rows[axis_at - 1], axes)
    rate = _frame_rate(p, meta)
    used, source = _length_units(p, meta, units)
    scale = unit_scale(used, f"{p} ({'Length Units' if source == 'file' else 'sheet units'})")
    values = _frame_values(p, rows[axis_at + 1:], axis_at + 1, meta, len(axes), rate,
                           [columns[name][a] for name in order for a in "XYZ"])
    xyz = values.reshape(len(values), len(order), 3) * scale
    return Recording(order, xyz, rate, source=str(p), units=used, units_source=source)


def _read_rows(p) -> list[list[str]]:
    """The file's CSV rows; line 1 must start with 'Format Version'."""
    from facemotion.io.base import check_last_line_ended

    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            text = fh.read()
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise InputError(f"{p}: cannot read Motive CSV text ({type(e).__name__})") from None
    if not rows or not rows[0] or rows[0][0].strip() != "Format Version":
        first = rows[0][0] if rows and rows[0] else ""
        raise InputError(f"{p}: not a Motive CSV export (line 1 starts with {token(first)}, not "
                         "'Format Version'; export with the header enabled)")
    check_last_line_ended(p, text.splitlines(keepends=True))
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
    if len(axes) <= 2:
        raise InputError(f"{p}: no columns after Frame and Time: the export holds no markers "
                         "(export with Markers enabled)")
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


def _frame_values(p, rows: list[list[str]], first_line: int, meta: dict, width: int,
                  rate: float, idx: list[int]) -> np.ndarray:
    """(frames, len(idx)) values of the non-blank data rows in columns ``idx``, the rows
    checked (:func:`check_motive_block`); an empty cell is NaN (an occluded marker)."""
    data = [(k + 1, r) for k, r in enumerate(rows, start=first_line) if any(c.strip() for c in r)]
    if not data:
        raise InputError(f"{p}: Motive CSV has no frames")
    numbers = [n for n, _ in data]
    frame_time = np.array([[_number(p, n, r, 0), _number(p, n, r, 1)] for n, r in data])
    check_motive_block(p, numbers, [len(r) for _, r in data], width, frame_time[:, 0],
                       frame_time[:, 1], rate, t0=frame_time[0, 1])
    total = meta.get("Total Exported Frames")
    if total and total.isdigit():
        check_frame_count(p, int(total), len(data), "Total Exported Frames")
    values = np.empty((len(data), len(idx)))
    for r, (line_no, row) in enumerate(data):
        values[r] = [_number(p, line_no, row, j) for j in idx]
    return values


def check_motive_block(p, numbers, n_fields, width: int, frames, times, rate: float,
                       t0: float, first_index: int = 0, previous_frame: float | None = None
                       ) -> None:
    """A block of Motive data rows (1-based line ``numbers``; the block's first frame is the
    take's ``first_index``-th; ``previous_frame`` the Frame before it): ``width`` fields each,
    Frame stepping by 1, Time on the export rate's grid from ``t0``."""
    check_field_counts(p, numbers, n_fields, width, "the 'Frame, Time' header row")
    check_frame_numbers(p, numbers, frames, previous_frame)
    check_time_grid(p, numbers, times, rate, t0, first_index,
                    rate_name="the Export Frame Rate", rounding_s=MOTIVE_TIME_ROUNDING_S)


def _number(p, line_no: int, row: list[str], j: int) -> float:
    """Cell ``j`` of a row as a float (NaN when empty); InputError naming line and column."""
    text = row[j].strip() if j < len(row) else ""
    if not text:
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{p}, line {line_no}: non-numeric value {token(row[j])} in "
                         f"column {j + 1}") from None
