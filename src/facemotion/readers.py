"""Readers and writers of marker trajectories: C3D (via ezc3d), TRC and wide CSV.

Every reader returns a :class:`~facemotion.recording.Recording` in millimetres with NaN for
missing samples. A marker that is missing in every frame is kept (all NaN); the gap check
(:mod:`facemotion.gaps`) reports it. Writers write to a temporary file in the target directory
and rename it, so a failed write never leaves a half-written file behind.

Units: a file that states its units (C3D ``POINT:UNITS``, the TRC header's ``Units``) is read in
them; the ``units`` argument (the subject sheet's) only applies to a file that does not say
(a CSV, or a C3D/TRC without units). The recording keeps the units used and where they came
from; :mod:`facemotion.validation` reports a sheet that disagrees with the file.

The readers are strict about layout, because a file that is cut short or has a field missing
can otherwise read back as a plausible, different recording: a C3D shorter than its header and
parameters declare, a TRC or CSV data line with fewer fields than the header, a text file whose
last line has no line end (cut off), a TRC time column off the DataRate grid are all errors
naming the file and the line. Messages never quote a file's content beyond a short token.
"""

from __future__ import annotations

import csv
import errno
import io
import logging
import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError, token
from facemotion.provenance import atomic_path
from facemotion.recording import Recording, finite_samples

FORMATS = ("c3d", "trc", "csv", "qualisys_tsv", "optitrack_csv", "openface_csv")
#: Parse regular TRC/CSV text with the C parser (benchmarks switch it off to compare).
FAST_TEXT = True

# Millimetres per unit, with the spellings found in C3D/TRC files.
_MM_PER_UNIT = {
    "mm": 1.0, "millimeter": 1.0, "millimeters": 1.0, "millimetre": 1.0, "millimetres": 1.0,
    "cm": 10.0, "centimeter": 10.0, "centimeters": 10.0, "centimetre": 10.0, "centimetres": 10.0,
    "m": 1000.0, "meter": 1000.0, "meters": 1000.0, "metre": 1000.0, "metres": 1000.0,
    "in": 25.4, "inch": 25.4, "inches": 25.4,
}


def unit_scale(unit: str, where: str) -> float:
    """Millimetres per ``unit`` (mm, cm, m, in); InputError naming ``where`` otherwise."""
    key = str(unit).strip().lower()
    if key not in _MM_PER_UNIT:
        raise InputError(f"{where}: unknown units {token(unit)} (supported: mm, cm, m, in)")
    return _MM_PER_UNIT[key]


#: Formats told by the file's suffix when none is given (the vendor exports need ``fmt``).
SUFFIX_FORMATS = {".c3d": "c3d", ".trc": "trc", ".csv": "csv"}


def infer_format(path) -> str:
    """The format of a file from its suffix (.c3d, .trc, .csv, any case)."""
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIX_FORMATS:
        raise InputError(f"{path}: cannot tell the format from the suffix "
                         f"{Path(path).suffix or '(none)'!r}; give the format "
                         f"({', '.join(FORMATS)})")
    return SUFFIX_FORMATS[suffix]


def read_recording(path, fmt: str | None = None, units: str | None = None,
                   subject_prefix: str | None = None) -> Recording:
    """Read one take (``facemotion.read``): labelled marker trajectories in mm.

    fmt: one of FORMATS; default: from the file's suffix (.c3d, .trc, .csv).
    units (mm, cm, m, in): the subject sheet's, applied only when the file does not state its
    own. Labels "Subject:Marker" lose their prefix; a file with several subjects needs
    ``subject_prefix`` (see :mod:`facemotion.input.prefixes`). Missing samples are NaN.
    """
    from facemotion.input.prefixes import select_subject

    fmt_key = infer_format(path) if fmt is None else str(fmt).strip().lower()
    readers = _readers()
    if fmt_key not in readers:
        raise InputError(f"{path}: unknown format {fmt!r} (supported: {', '.join(FORMATS)})")
    return select_subject(readers[fmt_key](path, units=units), subject_prefix)


def _readers() -> dict:
    """The reader of each of FORMATS (the vendor exports' readers live in facemotion.input)."""
    from facemotion.input.openface import read_openface_csv
    from facemotion.input.optitrack import read_optitrack_csv
    from facemotion.input.qualisys import read_qualisys_tsv

    return {"c3d": read_c3d, "trc": read_trc, "csv": read_csv,
            "qualisys_tsv": read_qualisys_tsv, "optitrack_csv": read_optitrack_csv,
            "openface_csv": read_openface_csv}


def read_labels(path, fmt: str, subject_prefix: str | None = None) -> list[str]:
    """The marker labels of a file, reading no more of it than needed (TRC and CSV: the
    header; C3D and the other exports: the whole file), without a subject prefix."""
    from facemotion.input.prefixes import subject_columns

    labels = _file_labels(path, fmt)
    return subject_columns(labels, subject_prefix, str(path))[1]


def _file_labels(path, fmt: str) -> list[str]:
    fmt_key = str(fmt).strip().lower()
    if fmt_key == "c3d":
        return read_c3d(path).labels
    if fmt_key in _readers() and fmt_key not in ("trc", "csv"):
        return _readers()[fmt_key](path).labels
    p = _check_readable(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            head = [fh.readline() for _ in range(4)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read as text ({type(e).__name__})") from None
    if fmt_key == "trc":
        if not head[0].startswith("PathFileType") or not head[3].startswith("Frame#"):
            raise InputError(f"{p}: not a TRC file (no PathFileType/Frame# header lines)")
        return [x.strip() for x in _split_line(head[3])[2:] if x.strip()]
    if fmt_key == "csv":
        cols = next(csv.reader([head[0]]), [])
        labels: list[str] = []
        for c in cols[1:]:
            lab = c.strip().rpartition("_")[0]
            if lab and lab not in labels:
                labels.append(lab)
        return labels
    raise InputError(f"{path}: unknown format {fmt!r} (supported: {', '.join(FORMATS)})")


def _check_readable(path) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: file not found")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a recording file")
    if not p.is_file():
        raise InputError(f"{p}: not a regular file")
    if not os.access(p, os.R_OK):
        raise InputError(f"{p}: file is not readable (permission denied)")
    return p


# ----------------------------------------------------------------------------------------- C3D

_C3D_PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}
C3D_MAX_FRAMES = 65535  # ezc3d writes the frame count as a 16-bit word


@dataclass
class C3DLayout:
    """What a C3D file's header (and parameters) declare about its data section."""

    processor: str          # Intel, DEC or MIPS (byte order and float format)
    points: int             # 3-D points per frame
    analog_per_frame: int   # analog samples per 3-D frame (all channels)
    first_frame: int
    last_frame: int
    frames: int
    float_storage: bool     # POINT:SCALE < 0: 4-byte floats, else 2-byte integers
    data_start: int         # byte offset of the data section

    @property
    def data_bytes(self) -> int:
        """Bytes of the data section: frames x (4 words per point + analog samples)."""
        word = 4 if self.float_storage else 2
        return self.frames * (4 * self.points + self.analog_per_frame) * word

    @property
    def size(self) -> int:
        """The smallest file size that holds every declared frame."""
        return self.data_start + self.data_bytes


def _c3d_float(raw: bytes, processor: str) -> float:
    if processor == "DEC":  # VAX F-float: 16-bit words swapped, exponent bias 2 more than IEEE
        return struct.unpack("<f", raw[2:4] + raw[0:2])[0] / 4.0
    return struct.unpack(">f" if processor == "MIPS" else "<f", raw)[0]


def _c3d_parameter(section: bytes, processor: str, group: str, name: str):
    """First value of parameter GROUP:NAME from a C3D parameter section (None if absent)."""
    end = ">" if processor == "MIPS" else "<"
    pos, groups, params = 4, {}, {}
    while pos + 2 <= len(section):
        nchars, ident = struct.unpack("bb", section[pos:pos + 2])
        if nchars == 0:
            break
        key = section[pos + 2:pos + 2 + abs(nchars)].decode("latin-1").strip().upper()
        off_at = pos + 2 + abs(nchars)
        if off_at + 2 > len(section):
            break
        (offset,) = struct.unpack(end + "h", section[off_at:off_at + 2])
        body = off_at + 2
        if ident < 0:
            groups[key] = -ident
        elif body + 2 <= len(section):
            dtype, ndim = struct.unpack("bb", section[body:body + 2])
            params[(ident, key)] = (dtype, section[body + 2 + ndim:body + 2 + ndim + 4])
        if offset <= 0:
            break
        pos = off_at + offset
    found = params.get((groups.get(group.upper()), name.upper()))
    if found is None:
        return None
    dtype, raw = found
    if dtype == 2 and len(raw) >= 2:
        return struct.unpack(end + "H", raw[:2])[0]
    if dtype == 4 and len(raw) >= 4:
        return _c3d_float(raw[:4], processor)
    if dtype == 1 and raw:
        return raw[0]
    return None


def c3d_layout(path) -> C3DLayout:
    """Read the layout a C3D file declares: its 512-byte header, and POINT:FRAMES when the
    header's 16-bit frame numbers cannot hold the count (the C3D User Guide's convention)."""
    p = Path(path)
    with open(p, "rb") as fh:
        head = fh.read(512)
        if len(head) < 512 or head[1] != 0x50:
            raise InputError(f"{p}: not a C3D file (no valid 512-byte header)")
        fh.seek((head[0] - 1) * 512)
        section = fh.read(255 * 512)
    if len(section) < 4 or section[3] not in _C3D_PROCESSORS:
        raise InputError(f"{p}: C3D parameter section is missing or cut short "
                         f"(processor type byte {section[3] if len(section) > 3 else None})")
    section = section[:max(section[2], 1) * 512]
    processor = _C3D_PROCESSORS[section[3]]
    end = ">" if processor == "MIPS" else "<"
    points, analog, first, last = struct.unpack(end + "4H", head[2:10])
    # sign of the scale factor (a float in the processor's format; only its sign bit matters)
    sign_byte = {"Intel": head[15], "DEC": head[13], "MIPS": head[12]}[processor]
    float_storage = bool(sign_byte & 0x80)
    (start_block,) = struct.unpack(end + "H", head[16:18])
    frames = last - first + 1
    if last == 0xFFFF or frames <= 0:
        declared = _c3d_parameter(section, processor, "POINT", "FRAMES")
        if declared is not None:
            frames = int(declared)
    return C3DLayout(processor, points, analog, first, last, max(frames, 0), float_storage,
                     (max(start_block, 1) - 1) * 512)


def check_c3d_size(path) -> C3DLayout:
    """InputError if the file is shorter than its header declares (cut in the data section,
    or its last bytes lost); ezc3d would otherwise read it with frames silently missing."""
    p = Path(path)
    layout = c3d_layout(p)
    size = p.stat().st_size
    if size < layout.size:
        per_frame = max(layout.data_bytes // max(layout.frames, 1), 1)
        whole = max(size - layout.data_start, 0) // per_frame
        raise InputError(
            f"{p}: C3D file is cut short: its header declares frames {layout.first_frame}-"
            f"{layout.first_frame + layout.frames - 1} ({layout.frames} frames) of "
            f"{layout.points} points and {layout.analog_per_frame} analog samples per frame in "
            f"{'float' if layout.float_storage else 'integer'} storage, {layout.size} bytes, "
            f"but the file has {size} bytes (only {whole} whole frames)")
    per_frame = layout.data_bytes // max(layout.frames, 1)
    # writers pad the data to whole 512-byte blocks (ezc3d adds a whole block when it is full)
    if per_frame and size - layout.size > 512 and size - layout.size >= per_frame:
        raise InputError(
            f"{p}: C3D file holds {size - layout.size} bytes after the {layout.frames} frames "
            f"its header declares (about {(size - layout.size) // per_frame} more frames): the "
            "header's frame count is wrong (e.g. more than 65535 frames)")
    return layout


def read_c3d(path, units: str | None = None) -> Recording:
    """Read the 3-D points of a C3D file with ezc3d.

    Labels come from POINT:LABELS (whitespace stripped), the rate from POINT:RATE and the units
    from POINT:UNITS (``units`` only for a file without them). The file's size is checked
    against its header first (:func:`check_c3d_size`). Points that POINT:ANGLES, FORCES,
    MOMENTS, POWERS, SCALARS, REACTIONS or MODELED_MARKERS list are not markers and are left
    out, with a log line (:mod:`facemotion.input.c3d_points`). Coordinates are taken at the
    32-bit precision C3D stores (floats, or 16-bit integers times a 32-bit scale), so the
    integer and real variants of one trial read identically. A sample is missing (NaN) if its
    residual is negative (C3D's "invalid" flag), if any coordinate is NaN, or if it is exactly
    (0, 0, 0) with a residual that is not positive (the exporters' other way of writing
    "no data").
    """
    import ezc3d

    from facemotion.input.c3d_points import describe_dropped, non_marker_points

    p = _check_readable(path)
    check_c3d_size(p)
    try:
        c = ezc3d.c3d(str(p))
    except Exception as e:  # ezc3d raises RuntimeError/IOError with terse messages
        raise InputError(f"{p}: cannot read as C3D ({type(e).__name__}: "
                         f"{str(e).splitlines()[0][:80] if str(e) else 'no detail'})") from None
    point = c["parameters"]["POINT"]
    data = np.asarray(c["data"]["points"], dtype=float)  # (4, markers, frames)
    n = data.shape[1]
    labels = [str(x).strip() for x in point["LABELS"]["value"]] if "LABELS" in point else []
    # Files with more than 255 points continue the labels in LABELS2, LABELS3, ...
    k = 2
    while len(labels) < n and f"LABELS{k}" in point:
        labels += [str(x).strip() for x in point[f"LABELS{k}"]["value"]]
        k += 1
    if len(labels) < n:
        raise InputError(f"{p}: POINT:LABELS has {len(labels)} labels for {n} points")
    labels = labels[:n]
    not_markers = non_marker_points(point, labels)
    if not_markers:
        logging.getLogger("facemotion").info(
            "%s: left out %d points that are not markers (%s)", p, len(not_markers),
            describe_dropped(not_markers))
    kept = [i for i, lab in enumerate(labels) if lab not in not_markers]
    if not kept:
        raise InputError(f"{p}: no marker points (all {n} points are "
                         f"{', '.join(sorted(set(not_markers.values())))})")
    labels = [labels[i] for i in kept]
    empty = [kept[i] for i, lab in enumerate(labels) if not lab]
    if empty:
        raise InputError(f"{p}: point(s) {empty[:5]} have an empty label in POINT:LABELS")
    rate_v = np.ravel(point["RATE"]["value"]) if "RATE" in point else np.array([])
    rate = float(rate_v[0]) if rate_v.size else float(c["header"]["points"]["frame_rate"])
    u = point["UNITS"]["value"] if "UNITS" in point else []
    u = [str(x).strip() for x in u] if not isinstance(u, str) else [u.strip()]
    if u and u[0]:
        used, source = u[0], "file"
    elif units is not None:
        used, source = units, "sheet"
    else:
        raise InputError(f"{p}: POINT:UNITS is missing; give the units in the subject sheet")
    scale = unit_scale(used, f"{p} ({'POINT:UNITS' if source == 'file' else 'sheet units'})")
    # (frames, markers, 3); float32 first: the precision the file stores (see the docstring)
    xyz = data[:3, kept].astype(np.float32).astype(float).transpose(2, 1, 0) * scale
    meta = c["data"].get("meta_points", {})
    if "residuals" in meta and np.size(meta["residuals"]):
        residual = np.asarray(meta["residuals"], dtype=float)[0, kept].T  # (frames, markers)
    else:
        residual = np.zeros(xyz.shape[:2])
    invalid = (residual < 0) | ~finite_samples(xyz)
    invalid |= (xyz[..., 0] == 0) & (xyz[..., 1] == 0) & (xyz[..., 2] == 0) & ~(residual > 0)
    xyz[invalid] = np.nan
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def write_c3d(path, rec: Recording) -> None:
    """Write the points of ``rec`` to a C3D file (mm; residual -1 where a sample is NaN)."""
    import ezc3d

    if rec.n_frames == 0:
        raise InputError(f"{path}: a recording without frames cannot be written to C3D")
    if rec.n_frames > C3D_MAX_FRAMES:
        raise InputError(f"{path}: {rec.n_frames} frames cannot be written to C3D (ezc3d "
                         f"writes at most {C3D_MAX_FRAMES}); write TRC or CSV")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rec.rate)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(rec.labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, rec.n_markers, rec.n_frames))
    pts[:3] = rec.points.transpose(2, 1, 0)
    bad = ~np.isfinite(rec.points).all(axis=2).T  # (markers, frames)
    pts[:3, bad] = np.nan
    c["data"]["points"] = pts
    residuals = np.zeros((1, rec.n_markers, rec.n_frames))
    residuals[0, bad] = -1.0
    c["data"]["meta_points"]["residuals"] = residuals
    c["data"]["meta_points"]["camera_masks"] = np.zeros((7, rec.n_markers, rec.n_frames),
                                                        dtype=bool)
    with atomic_path(path, suffix=".c3d") as tmp:  # ezc3d adds .c3d otherwise
        c.write(str(tmp))
        # ezc3d does not report a failed write (disk full, file-size limit): check the size
        try:
            check_c3d_size(tmp)
        except InputError:
            raise OSError(errno.EIO, "the written C3D file is incomplete (disk full or file-size "
                          "limit?)", str(path)) from None


# ----------------------------------------------------------------------------------------- TRC

def _split_line(line: str) -> list[str]:
    return line.rstrip("\r\n").split("\t")


def check_last_line_ended(path, lines: list[str]) -> None:
    """InputError if the text's last non-blank line has no line end (the file was cut)."""
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].strip(" \r\n"):
            if not lines[i].endswith("\n"):
                raise InputError(f"{path}: line {i + 1}, the last one, has no line end: the "
                                 "file looks cut short")
            return


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
    keys = [k.strip() for k in _split_line(lines[1])]
    vals = [v.strip() for v in _split_line(lines[2])]
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
    names = _split_line(lines[3])
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
    p = _check_readable(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            lines = [line for _, line in zip(range(5), fh, strict=False)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read TRC text ({type(e).__name__})") from None
    return _trc_header(p, lines, units)[1]


def read_trc(path, units: str | None = None) -> Recording:
    """Read a TRC file (OpenSim / Motion Analysis text format); empty fields are missing.

    Layout: ``PathFileType`` line; the header keys line (DataRate ... OrigNumFrames) and its
    values; ``Frame#  Time  label1 _ _ label2 ...``; ``_ _ X1 Y1 Z1 ...``; optional blank
    line; one line per frame: frame number, time, then x y z per marker, every field present
    (:func:`check_trc_fields`), times on the DataRate grid (:func:`check_trc_time`). The rate is
    DataRate; the units the header's Units (``units`` only when the header has none).

    Regular files are parsed at C-parser speed (:func:`_fast_numeric_lines`); anything the
    fast path does not take plainly goes through the exact line-by-line reader below, which
    gives the errors, so both return the same recording or the same error.
    """
    p = _check_readable(path)
    if FAST_TEXT:
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
        rows.append(_split_line(line))
        numbers.append(i)
    if len(rows) != n_frames:
        raise InputError(f"{p}: TRC header says NumFrames={n_frames} but there are "
                         f"{len(rows)} data lines")
    if not rows:
        raise InputError(f"{p}: TRC file has no frames")
    counts = np.array([len(r) for r in rows])
    check_trc_fields(p, numbers, counts, ncol,
                     [any(f.strip() for f in r[ncol:]) for r in rows])
    arr = np.array([r[:ncol] for r in rows], dtype=object)
    arr[arr == ""] = "nan"
    try:
        values = np.char.strip(arr.astype(str)).astype(float)
    except ValueError:
        bad = next((numbers[i], j, v) for i, r in enumerate(rows) for j, v in enumerate(r)
                   if v.strip() and not _is_float(v))
        raise InputError(f"{p}: non-numeric value {token(bad[2])} in line {bad[0]} "
                         f"field {bad[1] + 1}") from None
    check_trc_time(p, numbers, values[:, 0], values[:, 1], rate)
    xyz = values[:, 2:].reshape(n_frames, n_markers, 3) * scale
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def _read_trc_fast(p: Path, units: str | None) -> Recording | None:
    """The TRC reader's fast path: the header as in :func:`read_trc`, the data lines by
    :func:`_fast_numeric_lines`; None sends the file to the exact path."""
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
    got = _fast_numeric_lines(p, offset, 6, ncol, b"\t", max_rows=n_frames, empty_extra=True)
    if got is None:
        return None
    values, numbers = got
    check_trc_time(p, numbers, values[:, 0], values[:, 1], rate)
    xyz = values[:, 2:].reshape(n_frames, len(labels), 3)  # a view: no copy of the data
    if scale != 1.0:
        xyz *= scale
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _fmt(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.6f}"


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
        out.append(f"{f + 1}\t{f / rec.rate:.6f}\t" + "\t".join(_fmt(x) for x in flat[f]))
    with atomic_path(target) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")


# ----------------------------------------------------------------------------------------- CSV

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
    got = _fast_numeric_lines(p, offset, 2, len(cols), b",")
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
                if not _is_float(v):
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

    Regular files are parsed at C-parser speed (:func:`_fast_numeric_lines`); anything else
    goes through the exact reader (Python's csv module), which gives the errors.
    """
    p = _check_readable(path)
    fast = _read_csv_fast(p) if FAST_TEXT else None
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
        out.append(f"{f / rec.rate:.9g}," + ",".join(_fmt(x) for x in flat[f]))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")


# ------------------------------------------------------------------------- fast numeric tables

#: Bytes of text parsed per chunk by the fast path (bounds its temporary memory).
FAST_CHUNK_BYTES = 16 * 2**20


def _fast_numeric_lines(path: Path, offset: int, first_line: int, ncol: int, sep: bytes,
                        max_rows: int | None = None, empty_extra: bool = False):
    """Numeric data lines of a text table at C-parser speed, or None to use the exact path.

    Reads from byte ``offset`` (line number ``first_line``) in chunks of whole lines: numpy
    finds each line's end and counts its separators; pandas' C parser (quoting off, only an
    empty field is missing) converts the chunk. Returns (values (lines x ncol) float64, the
    1-based line number of each data line). Returns None whenever the text is not plainly
    regular - a line with another number of fields, a line of spaces, NUL or non-ASCII bytes,
    a last line without a line end, a token the C parser does not take as a number, other
    than ``max_rows`` lines when given - so that the exact line-by-line reader gives the error
    or the reading. Extra fields beyond ``ncol`` are taken only when empty and ``empty_extra``
    (TRC: some writers end lines with a tab; a CSV row must match its header). The values are
    those the exact reader returns (pandas' default float parser: identical on 300,000 random
    values written with 6 decimals, the writers' format).
    """
    import csv as _csv

    import pandas as pd

    sep_code = ord(sep)
    out = None if max_rows is None else np.empty((max_rows, ncol))
    blocks, numbers = [], []
    rows = 0
    line_no = first_line
    carry = b""
    with open(path, "rb") as fh:
        fh.seek(offset)
        while True:
            data = fh.read(FAST_CHUNK_BYTES)
            buf = carry + data
            if not data:
                if buf.strip(b" \r\n"):
                    return None  # last line without a line end: the exact path says so
                break
            cut = buf.rfind(b"\n") + 1
            if cut == 0:
                carry = buf
                continue
            chunk, carry = buf[:cut], buf[cut:]
            arr = np.frombuffer(chunk, dtype=np.uint8)
            if arr.max() >= 128 or not arr.all():
                return None  # NUL or non-ASCII text: the exact path decodes and judges it
            nl = np.flatnonzero(arr == 10)
            starts = np.concatenate([[0], nl[:-1] + 1])
            length = nl - starts
            cr = np.zeros(nl.size, dtype=bool)
            has = length > 0
            cr[has] = arr[nl[has] - 1] == 13
            length = length - cr
            seps = np.flatnonzero(arr == sep_code)  # separators per line, from positions
            fields = np.diff(np.concatenate([[0], np.searchsorted(seps, nl)])) + 1
            blank = length == 0
            if np.any((fields == 1) & ~blank & (ncol > 1)):
                return None  # a line without separators (spaces only, or one field)
            data_lines = ~blank
            f = fields[data_lines]
            if f.size == 0:
                line_no += nl.size
                continue
            if f.min() < ncol or (f.max() > ncol and not empty_extra):
                return None
            width = int(f.max())
            try:
                df = pd.read_csv(io.BytesIO(chunk), sep=sep.decode(), header=None,
                                 names=range(width), dtype=np.float64, engine="c",
                                 keep_default_na=False, na_values=[""],
                                 quoting=_csv.QUOTE_NONE, skip_blank_lines=True)
            except (ValueError, TypeError, pd.errors.ParserError):
                return None
            vals = df.to_numpy(dtype=np.float64)
            if vals.shape[0] != f.size:
                return None
            if width > ncol:
                if not np.isnan(vals[:, ncol:]).all():
                    return None  # text beyond the declared fields: the exact path's error
                vals = vals[:, :ncol]
            if out is not None:
                if rows + vals.shape[0] > max_rows:
                    return None
                out[rows:rows + vals.shape[0]] = vals
            else:
                blocks.append(np.ascontiguousarray(vals))
            rows += vals.shape[0]
            numbers.append(line_no + np.flatnonzero(data_lines))
            line_no += nl.size
    if rows == 0 or (out is not None and rows != max_rows):
        return None
    if out is not None:
        values = out
    else:
        values = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
    return values, np.concatenate(numbers)
