"""Readers and writers of marker trajectories: C3D (via ezc3d), TRC and wide CSV.

Every reader returns a :class:`~facemotion.recording.Recording` in millimetres with NaN for
missing samples. A marker that is missing in every frame is kept (all NaN); the gap check
(:mod:`facemotion.gaps`) reports it. Writers write to a temporary file in the target directory
and rename it, so a failed write never leaves a half-written file behind.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.recording import Recording

FORMATS = ("c3d", "trc", "csv")

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
        raise InputError(f"{where}: unknown units {unit!r} (supported: mm, cm, m, in)")
    return _MM_PER_UNIT[key]


def read_recording(path, fmt: str, units: str | None = None) -> Recording:
    """Read one take in format ``fmt`` ("c3d", "trc" or "csv"); ``units`` overrides the file's."""
    fmt_key = str(fmt).strip().lower()
    readers = {"c3d": read_c3d, "trc": read_trc, "csv": read_csv}
    if fmt_key not in readers:
        raise InputError(f"{path}: unknown format {fmt!r} (supported: {', '.join(FORMATS)})")
    return readers[fmt_key](path, units=units)


def _check_readable(path) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: file not found")
    if not p.is_file():
        raise InputError(f"{p}: not a regular file")
    if not os.access(p, os.R_OK):
        raise InputError(f"{p}: file is not readable (permission denied)")
    return p


@contextlib.contextmanager
def _atomic_path(path) -> Iterator[Path]:
    """A temporary path in the target's directory, renamed onto ``path`` if the block succeeds."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}",
                               dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# ----------------------------------------------------------------------------------------- C3D

def read_c3d(path, units: str | None = None) -> Recording:
    """Read the 3-D points of a C3D file with ezc3d.

    Labels come from POINT:LABELS (whitespace stripped), the rate from POINT:RATE and the units
    from POINT:UNITS (``units`` overrides). A sample is missing (NaN) if its residual is
    negative (C3D's "invalid" flag), if any coordinate is NaN, or if it is exactly (0, 0, 0)
    with a residual that is not positive (the exporters' other way of writing "no data").
    """
    import ezc3d

    p = _check_readable(path)
    try:
        c = ezc3d.c3d(str(p))
    except Exception as e:  # ezc3d raises RuntimeError/IOError with terse messages
        raise InputError(f"{p}: cannot read as C3D ({type(e).__name__}: "
                         f"{str(e).splitlines()[0] if str(e) else 'no detail'})") from None
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
    empty = [i for i, lab in enumerate(labels) if not lab]
    if empty:
        raise InputError(f"{p}: point(s) {empty[:5]} have an empty label in POINT:LABELS")
    rate_v = np.ravel(point["RATE"]["value"]) if "RATE" in point else np.array([])
    rate = float(rate_v[0]) if rate_v.size else float(c["header"]["points"]["frame_rate"])
    if units is None:
        u = point["UNITS"]["value"] if "UNITS" in point else []
        u = [str(x).strip() for x in u] if not isinstance(u, str) else [u.strip()]
        if not u or not u[0]:
            raise InputError(f"{p}: POINT:UNITS is missing; give the units in the settings")
        units = u[0]
    scale = unit_scale(units, f"{p} (POINT:UNITS)")
    xyz = data[:3].transpose(2, 1, 0) * scale  # (frames, markers, 3)
    meta = c["data"].get("meta_points", {})
    if "residuals" in meta and np.size(meta["residuals"]):
        residual = np.asarray(meta["residuals"], dtype=float)[0].T  # (frames, markers)
    else:
        residual = np.zeros(xyz.shape[:2])
    invalid = (residual < 0) | ~np.isfinite(xyz).all(axis=2)
    invalid |= (xyz == 0).all(axis=2) & ~(residual > 0)
    xyz[invalid] = np.nan
    return Recording(labels, xyz, rate, source=str(p))


def write_c3d(path, rec: Recording) -> None:
    """Write the points of ``rec`` to a C3D file (mm; residual -1 where a sample is NaN)."""
    import ezc3d

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
    with _atomic_path(path) as tmp:
        c.write(str(tmp))


# ----------------------------------------------------------------------------------------- TRC

def _split_line(line: str) -> list[str]:
    return line.rstrip("\r\n").split("\t")


def read_trc(path, units: str | None = None) -> Recording:
    """Read a TRC file (OpenSim / Motion Analysis text format); empty fields are missing.

    Layout: ``PathFileType`` line; the header keys line (DataRate ... OrigNumFrames) and its
    values; ``Frame#  Time  label1 _ _ label2 ...``; ``_ _ X1 Y1 Z1 ...``; optional blank
    line; one line per frame: frame number, time, then x y z per marker. The rate is
    DataRate; the units the header's Units (``units`` overrides).
    """
    p = _check_readable(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            lines = fh.readlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read TRC text ({e})") from None
    if not lines or not lines[0].startswith("PathFileType"):
        raise InputError(f"{p}: not a TRC file (first line does not start with PathFileType)")
    if len(lines) < 5:
        raise InputError(f"{p}: TRC header is incomplete ({len(lines)} lines)")
    keys = [k.strip() for k in _split_line(lines[1])]
    vals = [v.strip() for v in _split_line(lines[2])]
    header = dict(zip(keys, vals, strict=False))
    for key in ("DataRate", "NumFrames", "NumMarkers", "Units"):
        if not header.get(key):
            raise InputError(f"{p}: TRC header has no {key} value")
    try:
        rate = float(header["DataRate"])
        n_frames = int(float(header["NumFrames"]))
        n_markers = int(float(header["NumMarkers"]))
    except ValueError:
        raise InputError(f"{p}: TRC header DataRate/NumFrames/NumMarkers not numeric "
                         f"({header['DataRate']!r}, {header['NumFrames']!r}, "
                         f"{header['NumMarkers']!r})") from None
    if not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{p}: TRC DataRate must be positive, got {header['DataRate']!r}")
    scale = unit_scale(units if units is not None else header["Units"],
                       f"{p} ({'units setting' if units is not None else 'TRC Units'})")
    names = _split_line(lines[3])
    if not names or names[0].strip() != "Frame#":
        raise InputError(f"{p}: TRC line 4 should start with 'Frame#', got {names[0]!r}")
    labels = [x.strip() for x in names[2:] if x.strip()]
    if len(labels) != n_markers:
        raise InputError(f"{p}: TRC header says NumMarkers={n_markers} but line 4 names "
                         f"{len(labels)} markers")
    ncol = 2 + 3 * n_markers
    rows = []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        fields = _split_line(line)
        if len(fields) > ncol:
            if any(f.strip() for f in fields[ncol:]):
                raise InputError(f"{p}: line {i} has {len(fields)} fields, expected {ncol}")
            fields = fields[:ncol]
        elif len(fields) < ncol:  # trailing missing markers may be cut off
            fields = fields + [""] * (ncol - len(fields))
        rows.append(fields)
    if len(rows) != n_frames:
        raise InputError(f"{p}: TRC header says NumFrames={n_frames} but there are "
                         f"{len(rows)} data lines")
    if not rows:
        raise InputError(f"{p}: TRC file has no frames")
    arr = np.array(rows, dtype=object)
    arr[arr == ""] = "nan"
    try:
        values = np.char.strip(arr.astype(str)).astype(float)
    except ValueError:
        bad = next((i + 6, j, v) for i, r in enumerate(rows) for j, v in enumerate(r)
                   if v.strip() and not _is_float(v))
        raise InputError(f"{p}: non-numeric value {bad[2]!r} in data line {bad[0]} "
                         f"field {bad[1] + 1}") from None
    xyz = values[:, 2:].reshape(n_frames, n_markers, 3) * scale
    return Recording(labels, xyz, rate, source=str(p))


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
    with _atomic_path(target) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")


# ----------------------------------------------------------------------------------------- CSV

def read_csv(path, units: str | None = None) -> Recording:
    """Read a wide CSV: ``time`` (s), then ``<label>_x``, ``<label>_y``, ``<label>_z`` columns.

    The rate is 1 / (the time step), which must be uniform (within 1 % of the mean step).
    Units are mm unless ``units`` is given. Empty cells are missing samples.
    """
    import pandas as pd

    p = _check_readable(path)
    try:
        df = pd.read_csv(p, dtype=str, keep_default_na=False)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as e:
        raise InputError(f"{p}: cannot read as CSV ({str(e).splitlines()[0]})") from None
    cols = [str(c).strip() for c in df.columns]
    if not cols or cols[0] != "time":
        raise InputError(f"{p}: first column must be 'time', got {cols[0] if cols else None!r}")
    labels: list[str] = []
    axes: dict[str, dict[str, int]] = {}
    for j, col in enumerate(cols[1:], start=1):
        label, sep, axis = col.rpartition("_")
        if not sep or not label or axis not in ("x", "y", "z"):
            raise InputError(f"{p}: column {col!r} is not of the form <label>_x/_y/_z")
        if label not in axes:
            labels.append(label)
            axes[label] = {}
        if axis in axes[label]:
            raise InputError(f"{p}: column {col!r} appears twice")
        axes[label][axis] = j
    for label in labels:
        lacking = [a for a in "xyz" if a not in axes[label]]
        if lacking:
            raise InputError(f"{p}: marker {label!r} has no column(s) "
                             + ", ".join(f"{label}_{a}" for a in lacking))
    raw = df.to_numpy(dtype=object)
    raw = np.where(np.char.strip(raw.astype(str)) == "", "nan", raw)
    try:
        values = raw.astype(float)
    except ValueError:
        for j, col in enumerate(cols):
            for i, v in enumerate(raw[:, j]):
                if not _is_float(v):
                    raise InputError(f"{p}: non-numeric value {v!r} in column {col!r} "
                                     f"row {i + 2}") from None
        raise
    t = values[:, 0]
    if t.size < 2:
        raise InputError(f"{p}: need at least 2 frames to get the rate from 'time'")
    if not np.isfinite(t).all():
        raise InputError(f"{p}: column 'time' has empty or non-finite values")
    dt = np.diff(t)
    step = (t[-1] - t[0]) / (t.size - 1)
    if step <= 0 or np.max(np.abs(dt - step)) > 0.01 * step:
        k = int(np.argmax(np.abs(dt - step)))
        raise InputError(f"{p}: column 'time' is not uniformly sampled (step {dt[k]:.6g} s "
                         f"at row {k + 3} vs mean step {step:.6g} s)")
    rate = round(1.0 / step, 3)
    scale = unit_scale(units, f"{p} (units setting)") if units is not None else 1.0
    idx = [axes[label][a] for label in labels for a in "xyz"]
    xyz = values[:, idx].reshape(t.size, len(labels), 3) * scale
    return Recording(labels, xyz, rate, source=str(p))


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
    with _atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
