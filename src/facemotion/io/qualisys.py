"""Qualisys Track Manager (QTM) TSV export of 3-D trajectories.

Layout (QTM manual, "Motion data (.tsv)"): a header of one variable per line, the name, a tab
and the value(s) (FILE_VERSION, NO_OF_FRAMES, NO_OF_CAMERAS, NO_OF_MARKERS, FREQUENCY,
NO_OF_ANALOG, ANALOG_FREQUENCY, DESCRIPTION, TIME_STAMP, DATA_INCLUDED, EVENT lines,
MARKER_NAMES with one tab-separated name per trajectory, TRAJECTORY_TYPES); then, in newer
exports, a column-header line ``Frame  Time  <name> X  <name> Y  <name> Z ...``; then one line
per frame with X, Y, Z per trajectory (preceded by frame number and time when exported).
Coordinates are in mm. A sample is missing when its fields are empty (or NaN/NULL), or when
all three are exactly 0 (how QTM writes a missing sample when null data is written as zero).

Checked as strictly as a TRC file (:func:`check_qtm_block`, which also runs on a block of
lines): every data line has the fields of the column header (or of the first line), the Frame
column steps by 1, the Time column lies on the grid of FREQUENCY, the lines are NO_OF_FRAMES
and the last one ends with a line end. A file without the header block, and 6D (rigid body)
and 2D exports, are refused as such.
"""

from __future__ import annotations

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

_KEY = re.compile(r"^[A-Z][A-Z0-9_]*$")
_MISSING = {"", "nan", "null", "-"}


def _float(text: str) -> float:
    t = text.strip()
    if t.lower() in _MISSING:
        return math.nan
    return float(t)


#: QTM writes Time with 5 decimals.
QTM_TIME_ROUNDING_S = 0.5e-5


def read_qualisys_tsv(path, units: str | None = None) -> Recording:
    """Read a QTM 3-D TSV export (see the module docstring); always mm (``units`` unused)."""
    from facemotion.io.base import check_last_line_ended, check_readable

    p = check_readable(path)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read QTM TSV text ({type(e).__name__})") from None
    lines = text.splitlines()
    header, i = _header(lines)
    n_frames, n_markers, rate, names = _checked_header(p, header)
    check_last_line_ended(p, text.splitlines(keepends=True))
    cols: list[int] | None = None
    width = None
    if i < len(lines) and lines[i].split("\t")[0].strip() == "Frame":
        cols, width = _named_columns(p, lines[i], names)
        i += 1
    rows = [(k + 1, line) for k, line in enumerate(lines[i:], start=i) if line.strip()]
    if not rows:
        raise InputError(f"{p}: QTM TSV file has no frames")
    if cols is None:
        cols, width = _positional_columns(p, rows[0], n_markers)
    fields = [line.split("\t") for _, line in rows]
    numbers = [n for n, _ in rows]
    check_qtm_block(p, numbers, fields, width, rate, has_frame_time=cols[0] == 2)
    check_frame_count(p, n_frames, len(rows), "NO_OF_FRAMES")
    xyz = _frame_values(p, numbers, fields, cols).reshape(n_frames, n_markers, 3)
    xyz[(xyz == 0).all(axis=2)] = np.nan
    # QTM exports 3-D data in mm: the format's own units win over the sheet's
    return Recording(names, xyz, rate, source=str(p), units="mm", units_source="file")


def check_qtm_block(p, numbers, fields: list[list[str]], width: int, rate: float,
                    has_frame_time: bool, t0: float | None = None, first_index: int = 0,
                    previous_frame: float | None = None) -> None:
    """A block of QTM data lines (1-based ``numbers``, split ``fields``; the block's first
    frame is the take's ``first_index``-th, ``previous_frame`` the Frame before it, ``t0`` the
    take's first Time): ``width`` fields (empty ones beyond allowed), and with Frame and Time
    columns, Frame stepping by 1 and Time on the FREQUENCY grid."""
    used = [len(f) - _trailing_empty(f, width) for f in fields]
    check_field_counts(p, numbers, used, width, "the column header (or first line)")
    if not has_frame_time:
        return
    frame = np.array([_number(p, n, f, 0) for n, f in zip(numbers, fields, strict=True)])
    time = np.array([_number(p, n, f, 1) for n, f in zip(numbers, fields, strict=True)])
    check_frame_numbers(p, numbers, frame, previous_frame)
    check_time_grid(p, numbers, time, rate, time[0] if t0 is None else t0, first_index,
                    rate_name="FREQUENCY", rounding_s=QTM_TIME_ROUNDING_S)


def _trailing_empty(fields: list[str], width: int) -> int:
    """Empty fields after the first ``width`` (QTM may end a line with a tab)."""
    k = 0
    while len(fields) - k > width and not fields[len(fields) - k - 1].strip():
        k += 1
    return k


def _header(lines: list[str]) -> tuple[dict[str, list[str]], int]:
    """The header's variables (EVENT lines left out) and the index of the first line after."""
    header: dict[str, list[str]] = {}
    i = 0
    while i < len(lines):
        fields = lines[i].split("\t")
        key = fields[0].strip()
        if not _KEY.match(key):
            break
        if key != "EVENT":
            header[key] = [f.strip() for f in fields[1:]]
        i += 1
    return header, i


def _checked_header(p, header: dict[str, list[str]]) -> tuple[int, int, float, list[str]]:
    """Frames, markers, rate (Hz) and marker names of a 3-D export's header, checked."""
    if "NO_OF_FRAMES" not in header and "MARKER_NAMES" not in header:
        raise InputError(f"{p}: not a QTM TSV export, or one without its header block (no "
                         "NO_OF_FRAMES, FREQUENCY or MARKER_NAMES; export with 'Include TSV "
                         "header')")
    included = (header.get("DATA_INCLUDED") or [""])[0].upper()
    if included == "6D" or "BODY_NAMES" in header or "NO_OF_BODIES" in header:
        raise InputError(f"{p}: a QTM 6D export (rigid bodies), no markers; export 3D "
                         "trajectories")
    if included and included != "3D":
        raise InputError(f"{p}: QTM TSV holds {token(included)} data, no 3D markers; export "
                         "3D trajectories")
    for key in ("NO_OF_FRAMES", "NO_OF_MARKERS", "FREQUENCY", "MARKER_NAMES"):
        if key not in header or not header[key] or not header[key][0]:
            raise InputError(f"{p}: QTM TSV header has no {key} value")
    try:
        n_frames = int(header["NO_OF_FRAMES"][0])
        n_markers = int(header["NO_OF_MARKERS"][0])
    except ValueError:
        raise InputError(f"{p}: NO_OF_FRAMES/NO_OF_MARKERS not integers "
                         f"({token(header['NO_OF_FRAMES'][0])}, "
                         f"{token(header['NO_OF_MARKERS'][0])})") from None
    freq = header["FREQUENCY"][0]
    try:
        rate = float(freq)
    except ValueError:
        raise InputError(f"{p}: FREQUENCY {token(freq)} is not a number (an external timebase "
                         "export has no fixed rate)") from None
    if not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{p}: FREQUENCY must be positive, got {token(freq)}")
    names = list(header["MARKER_NAMES"])
    while names and not names[-1]:
        names.pop()
    if len(names) != n_markers:
        raise InputError(f"{p}: NO_OF_MARKERS is {n_markers} but MARKER_NAMES lists "
                         f"{len(names)} names")
    if any(not n for n in names):
        raise InputError(f"{p}: MARKER_NAMES has an empty name (trajectory "
                         f"{names.index('') + 1})")
    return n_frames, n_markers, rate, names


def _named_columns(p, line: str, names: list[str]) -> tuple[list[int], int]:
    """Each marker's X, Y, Z columns, by name in the column header (newer exports), and the
    header's number of fields (empty ones at its end not counted)."""
    heads = [h.strip() for h in line.split("\t")]
    while heads and not heads[-1]:
        heads.pop()
    where = {h: j for j, h in enumerate(heads)}
    if heads[:2] != ["Frame", "Time"]:
        raise InputError(f"{p}: the column header must start with Frame, Time")
    cols = []
    for name in names:
        for axis in "XYZ":
            col = where.get(f"{name} {axis}")
            if col is None:
                raise InputError(f"{p}: column header has no '{name} {axis}' column")
            cols.append(col)
    return cols, len(heads)


def _positional_columns(p, first_row: tuple[int, str], n_markers: int) -> tuple[list[int], int]:
    """Without a column header: X Y Z per marker, maybe after frame and time."""
    width = len(first_row[1].rstrip("\t").split("\t"))
    if width == 3 * n_markers:
        first = 0
    elif width == 3 * n_markers + 2:
        first = 2
    else:
        raise InputError(f"{p}, line {first_row[0]}: {width} fields, expected "
                         f"{3 * n_markers} (X, Y, Z of {n_markers} markers) or "
                         f"{3 * n_markers + 2} (with frame and time)")
    return list(range(first, first + 3 * n_markers)), width


def _frame_values(p, numbers, fields: list[list[str]], cols: list[int]) -> np.ndarray:
    """(frames, len(cols)) values of the data lines; an empty field is NaN."""
    values = np.empty((len(fields), len(cols)))
    for r, (line_no, f) in enumerate(zip(numbers, fields, strict=True)):
        values[r] = [_number(p, line_no, f, c) for c in cols]
    return values


def _number(p, line_no: int, fields: list[str], c: int) -> float:
    try:
        return _float(fields[c])
    except ValueError:
        raise InputError(f"{p}, line {line_no}: non-numeric value {token(fields[c])} in "
                         f"field {c + 1}") from None
