"""TRC files (OpenSim / Motion Analysis): header, strict data lines, writer."""

from __future__ import annotations

import math
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
    split_tab_line,
    unit_scale,
)
from facemotion.io.recording import Recording


def check_trc_fields(path, line_numbers, n_fields, ncol: int, extra_nonempty=None) -> None:
    """The TRC rule for data lines, for any TRC parser: exactly ``ncol`` tab-separated fields.

    ``line_numbers`` (1-based), ``n_fields`` (fields of each data line) and, optionally,
    ``extra_nonempty`` (True where a line with more than ``ncol`` fields has text beyond them)
    are arrays over the data lines. A line with fewer fields is an error, because every later
    value would move to another axis or marker; a missing sample is an empty field between
    tabs. Trailing empty fields beyond ``ncol`` are allowed (some writers end lines with a tab).
    """
    n_fields = np.asarray(n_fields)
    short = np.flatnonzero(n_fields < ncol)
    if short.size:
        i = int(short[0])
        raise InputError(f"{path}: line {int(line_numbers[i])} has {int(n_fields[i])} fields but "
                         f"the header declares {ncol} (frame, time, x y z per marker); a "
                         "missing sample must be empty fields between tabs")
    if extra_nonempty is not None:
        extra = np.flatnonzero(np.asarray(extra_nonempty, dtype=bool) & (n_fields > ncol))
        if extra.size:
            i = int(extra[0])
            raise InputError(f"{path}: line {int(line_numbers[i])} has {int(n_fields[i])} "
                             f"fields but the header declares {ncol}")


def check_trc_time(path, line_numbers, frame_numbers, times, rate: float) -> None:
    """Frame numbers increase and the Time column lies on the 1/DataRate grid.

    A time more than a quarter of a frame off ``t0 + i / rate`` (a dropped, repeated or
    reordered line, or a DataRate that does not match the data) is an error naming the line.
    """
    frame_numbers = np.asarray(frame_numbers, dtype=float)
    times = np.asarray(times, dtype=float)
    bad = np.flatnonzero(~np.isfinite(frame_numbers) | ~np.isfinite(times))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: Frame# and Time must be numbers")
    steps = np.flatnonzero(np.diff(frame_numbers) <= 0)
    if steps.size:
        i = int(steps[0]) + 1
        raise InputError(f"{path}: line {int(line_numbers[i])}: Frame# {frame_numbers[i]:g} does "
                         f"not follow {frame_numbers[i - 1]:g}")
    grid = times[0] + np.arange(times.size) / rate
    off = np.flatnonzero(np.abs(times - grid) > 0.25 / rate)
    if off.size:
        i = int(off[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: Time {times[i]:.6g} s is off the "
                         f"1/DataRate grid (expected {grid[i]:.6g} s at {rate:g} Hz): a frame is "
                         "missing, repeated or out of order, or DataRate is wrong")


def _trc_header(p: Path, lines: list[str], units: str | None):
    """The TRC header (lines 1-5): (rate, n_frames, labels, scale, units used, their source)."""
    if not lines or not lines[0].startswith("PathFileType"):
        raise InputError(f"{p}: not a TRC file (first line does not start with PathFileType)")
    if len(lines) < 5:
        raise InputError(f"{p}: TRC header is incomplete ({len(lines)} lines)")
    if "\t" not in lines[1] and "," in lines[1]:
        raise InputError(f"{p}: TRC header line 2 is comma-separated, not tab-separated (a TRC "
                         "saved as CSV); save it with tabs")
    keys = [k.strip() for k in split_tab_line(lines[1])]
    vals = [v.strip() for v in split_tab_line(lines[2])]
    if len(vals) > len(keys) and len([v for v in vals if v]) == len(keys):
        vals = [v for v in vals if v]  # repeated tabs between the values (OpenSim's own files)
    if len(vals) > len(keys) and any(vals[len(keys):]):
        raise InputError(f"{p}: TRC line 3 has {len(vals)} header values for {len(keys)} keys")
    header = dict(zip(keys, vals, strict=False))
    for key in ("DataRate", "NumFrames", "NumMarkers"):
        if not header.get(key):
            raise InputError(f"{p}: TRC header has no {key} value")
    try:
        rate = float(header["DataRate"])
        n_frames, n_markers = (float(header[k]) for k in ("NumFrames", "NumMarkers"))
        if not (n_frames.is_integer() and n_markers.is_integer()):
            raise ValueError
        n_frames, n_markers = int(n_frames), int(n_markers)
    except ValueError:
        raise InputError(f"{p}: TRC header DataRate/NumFrames/NumMarkers not numeric "
                         f"({token(header['DataRate'])}, {token(header['NumFrames'])}, "
                         f"{token(header['NumMarkers'])})") from None
    if not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{p}: TRC DataRate must be positive, got {token(header['DataRate'])}")
    if header.get("Units"):
        used, source = header["Units"], "file"
    elif units is not None:
        used, source = units, "sheet"
    else:
        raise InputError(f"{p}: TRC header has no Units value; give the units in the sheet")
    scale = unit_scale(used, f"{p} ({'TRC Units' if source == 'file' else 'sheet units'})")
    names = split_tab_line(lines[3])
    if not names or names[0].strip() != "Frame#":
        raise InputError(f"{p}: TRC line 4 should start with 'Frame#', got {token(names[0])}")
    labels = [x.strip() for x in names[2:] if x.strip()]
    if len(labels) != n_markers:
        raise InputError(f"{p}: TRC header says NumMarkers={n_markers} but line 4 names "
                         f"{len(labels)} markers")
    return rate, n_frames, labels, scale, used, source


def trc_frame_count(path, units: str | None = None) -> int:
    """A TRC file's number of frames from its header alone (NumFrames, checked like
    :func:`read_trc` checks the header). :func:`read_trc` stops on a file whose data lines
    are not NumFrames, so the count is the frames the file gives when it can be read."""
    p = check_readable(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            lines = [line for _, line in zip(range(5), fh, strict=False)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read TRC text ({type(e).__name__})") from None
    return _trc_header(p, lines, units)[1]


def parse_trc_rows(p, numbers, rows: list[list[str]], ncol: int) -> np.ndarray:
    """Data lines split into fields (``numbers``: their line numbers) as a (lines x ncol)
    float array: the field counts checked (:func:`check_trc_fields`), empty fields NaN, and
    a field that is not a number named by its line and field."""
    check_trc_fields(p, numbers, np.array([len(r) for r in rows]), ncol,
                     [any(f.strip() for f in r[ncol:]) for r in rows])
    arr = np.array([r[:ncol] for r in rows], dtype=object)
    arr[arr == ""] = "nan"
    try:
        return np.char.strip(arr.astype(str)).astype(float)
    except ValueError:
        bad = next((numbers[i], j, v) for i, r in enumerate(rows) for j, v in enumerate(r)
                   if v.strip() and not is_float(v))
        raise InputError(f"{p}: non-numeric value {token(bad[2])} in line {bad[0]} "
                         f"field {bad[1] + 1}") from None


def read_trc(path, units: str | None = None) -> Recording:
    """Read a TRC file (OpenSim / Motion Analysis text format); empty fields are missing.

    Layout: ``PathFileType`` line; the header keys line (DataRate ... OrigNumFrames) and its
    values; ``Frame#  Time  label1 _ _ label2 ...``; ``_ _ X1 Y1 Z1 ...``; optional blank
    line; one line per frame: frame number, time, then x y z per marker, every field present
    (:func:`check_trc_fields`), times on the DataRate grid (:func:`check_trc_time`). The rate is
    DataRate; the units the header's Units (``units`` only when the header has none).

    Regular files are parsed at C-parser speed (:func:`fast_numeric_lines`); anything the
    fast path does not take plainly goes through the exact line-by-line reader below, which
    gives the errors, so both return the same recording or the same error.
    """
    p = check_readable(path)
    if base.FAST_TEXT:
        rec = _read_trc_fast(p, units)
        if rec is not None:
            return rec
    try:
        with open(p, encoding="utf-8-sig") as fh:
            lines = fh.readlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read TRC text ({type(e).__name__})") from None
    if lines and lines[0].startswith("PathFileType") and len(lines) >= 5:
        check_last_line_ended(p, lines)  # before the header's checks, as always
    rate, n_frames, labels, scale, used, source = _trc_header(p, lines, units)
    n_markers = len(labels)
    ncol = 2 + 3 * n_markers
    rows, numbers = [], []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip(" \r\n"):  # blank; a line of tabs is a frame with empty fields
            continue
        rows.append(split_tab_line(line))
        numbers.append(i)
    if len(rows) != n_frames:
        raise InputError(f"{p}: TRC header says NumFrames={n_frames} but there are "
                         f"{len(rows)} data lines")
    if not rows:
        raise InputError(f"{p}: TRC file has no frames")
    values = parse_trc_rows(p, numbers, rows, ncol)
    check_trc_time(p, numbers, values[:, 0], values[:, 1], rate)
    xyz = values[:, 2:].reshape(n_frames, n_markers, 3) * scale
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def _read_trc_fast(p: Path, units: str | None) -> Recording | None:
    """The TRC reader's fast path: the header as in :func:`read_trc`, the data lines by
    :func:`fast_numeric_lines`; None sends the file to the exact path."""
    try:
        with open(p, "rb") as fh:
            head = [fh.readline() for _ in range(5)]
            offset = fh.tell()
        lines = [h.decode("utf-8-sig" if i == 0 else "utf-8") for i, h in enumerate(head)]
    except (OSError, UnicodeDecodeError):
        return None
    if len(lines[-1]) == 0 or not lines[-1].endswith("\n"):
        return None
    try:
        rate, n_frames, labels, scale, used, source = _trc_header(p, lines, units)
    except InputError:
        return None  # the exact path reports it, in its order of checks
    ncol = 2 + 3 * len(labels)
    if n_frames < 1:
        return None
    got = fast_numeric_lines(p, offset, 6, ncol, b"\t", max_rows=n_frames, empty_extra=True)
    if got is None:
        return None
    values, numbers = got
    check_trc_time(p, numbers, values[:, 0], values[:, 1], rate)
    xyz = values[:, 2:].reshape(n_frames, len(labels), 3)  # a view: no copy of the data
    if scale != 1.0:
        xyz *= scale
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def write_trc(path, rec: Recording) -> None:
    """Write ``rec`` as a TRC file in mm (missing samples as empty fields)."""
    target = Path(path)
    n, F = rec.n_markers, rec.n_frames
    rate = f"{rec.rate:.6g}"
    out = [
        f"PathFileType\t4\t(X/Y/Z)\t{target.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate}\t{rate}\t{F}\t{n}\tmm\t{rate}\t1\t{F}",
        "Frame#\tTime\t" + "\t".join(f"{lab}\t\t" for lab in rec.labels),
        "\t\t" + "\t".join(f"X{j}\tY{j}\tZ{j}" for j in range(1, n + 1)),
        "",
    ]
    flat = rec.points.reshape(F, 3 * n)
    for f in range(F):
        out.append(f"{f + 1}\t{f / rec.rate:.6f}\t"
                   + "\t".join(format_coordinate(x) for x in flat[f]))
    with atomic_path(target) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")


def read_trc_labels(path) -> list[str]:
    """A TRC file's marker labels from its header lines alone."""
    p, head = head_lines(path, 4)
    if not head[0].startswith("PathFileType") or not head[3].startswith("Frame#"):
        raise InputError(f"{p}: not a TRC file (no PathFileType/Frame# header lines)")
    return [x.strip() for x in split_tab_line(head[3])[2:] if x.strip()]
