"""Qualisys Track Manager (QTM) TSV export of 3-D trajectories.

Layout (QTM manual, "Motion data (.tsv)"): a header of one variable per line, the name, a tab
and the value(s) (FILE_VERSION, NO_OF_FRAMES, NO_OF_CAMERAS, NO_OF_MARKERS, FREQUENCY,
NO_OF_ANALOG, ANALOG_FREQUENCY, DESCRIPTION, TIME_STAMP, DATA_INCLUDED, EVENT lines,
MARKER_NAMES with one tab-separated name per trajectory, TRAJECTORY_TYPES); then, in newer
exports, a column-header line ``Frame  Time  <name> X  <name> Y  <name> Z ...``; then one line
per frame with X, Y, Z per trajectory (preceded by frame number and time when exported).
Coordinates are in mm. A sample is missing when its fields are empty (or NaN/NULL), or when
all three are exactly 0 (how QTM writes a missing sample when null data is written as zero).
"""

from __future__ import annotations

import math
import re

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.recording import Recording

_KEY = re.compile(r"^[A-Z][A-Z0-9_]*$")
_MISSING = {"", "nan", "null", "-"}


def _float(text: str) -> float:
    t = text.strip()
    if t.lower() in _MISSING:
        return math.nan
    return float(t)


def read_qualisys_tsv(path, units: str | None = None) -> Recording:
    """Read a QTM 3-D TSV export (see the module docstring); always mm (``units`` unused)."""
    from facemotion.io.base import check_readable

    p = check_readable(path)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read QTM TSV text ({e})") from None
    header, i = _header(lines)
    n_frames, n_markers, rate, names = _checked_header(p, header)
    cols: list[int] | None = None
    if i < len(lines) and lines[i].split("\t")[0].strip() == "Frame":
        cols = _named_columns(p, lines[i], names)
        i += 1
    rows = [(k + 1, line) for k, line in enumerate(lines[i:], start=i) if line.strip()]
    if len(rows) != n_frames:
        raise InputError(f"{p}: NO_OF_FRAMES is {n_frames} but there are {len(rows)} data lines")
    if not rows:
        raise InputError(f"{p}: QTM TSV file has no frames")
    if cols is None:
        cols = _positional_columns(p, rows[0], n_markers)
    xyz = _frame_values(p, rows, cols).reshape(n_frames, n_markers, 3)
    xyz[(xyz == 0).all(axis=2)] = np.nan
    # QTM exports 3-D data in mm: the format's own units win over the sheet's
    return Recording(names, xyz, rate, source=str(p), units="mm", units_source="file")


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
        raise InputError(f"{p}: not a QTM TSV export (no NO_OF_FRAMES / MARKER_NAMES header; "
                         "export with 'Include TSV header')")
    for key in ("NO_OF_FRAMES", "NO_OF_MARKERS", "FREQUENCY", "MARKER_NAMES"):
        if key not in header or not header[key] or not header[key][0]:
            raise InputError(f"{p}: QTM TSV header has no {key} value")
    included = (header.get("DATA_INCLUDED") or ["3D"])[0].upper()
    if included != "3D":
        raise InputError(f"{p}: QTM TSV holds {included} data; export 3D trajectories")
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


def _named_columns(p, line: str, names: list[str]) -> list[int]:
    """Each marker's X, Y, Z columns, by name in the column header (newer exports)."""
    heads = [h.strip() for h in line.split("\t")]
    where = {h: j for j, h in enumerate(heads)}
    cols = []
    for name in names:
        for axis in "XYZ":
            col = where.get(f"{name} {axis}")
            if col is None:
                raise InputError(f"{p}: column header has no '{name} {axis}' column")
            cols.append(col)
    return cols


def _positional_columns(p, first_row: tuple[int, str], n_markers: int) -> list[int]:
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
    return list(range(first, first + 3 * n_markers))


def _frame_values(p, rows: list[tuple[int, str]], cols: list[int]) -> np.ndarray:
    """(frames, len(cols)) values of the data lines (line number, text); empty is NaN."""
    need = max(cols) + 1
    values = np.empty((len(rows), len(cols)))
    for r, (line_no, line) in enumerate(rows):
        fields = line.split("\t")
        if len(fields) < need:
            fields += [""] * (need - len(fields))
        try:
            values[r] = [_float(fields[c]) for c in cols]
        except ValueError:
            bad = next(c for c in cols if not _is_number(fields[c]))
            raise InputError(f"{p}, line {line_no}: non-numeric value {token(fields[bad])} in "
                             f"field {bad + 1}") from None
    return values


def _is_number(text: str) -> bool:
    try:
        _float(text)
    except ValueError:
        return False
    return True
