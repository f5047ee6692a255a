"""OpenFace 2.x landmark CSV (FeatureExtraction / FaceLandmarkVid output).

Layout (OpenFace wiki, "Output Format"): one row per video frame with columns ``frame``
(1-based), ``face_id``, ``timestamp`` (s), ``confidence``, ``success``, ..., the 2-D landmarks
``x_0 .. x_67``, ``y_0 .. y_67`` (pixels) and the 3-D landmarks ``X_0 .. X_67``, ``Y_0 ..``,
``Z_0 ..`` in millimetres in the camera's frame; column names may have a leading space.

The 3-D landmarks are read as markers ``L0 .. L67`` (OpenFace's landmark numbers), in mm. A
frame with ``success`` 0 (no face tracked) is a missing sample of every landmark. The rate is
1 / the step of ``timestamp`` (least-squares slope, rounded to 0.01 Hz), which must be uniform
(no timestamp further than a quarter step from the fitted grid; a skipped frame is an error).
Camera coordinates include the motion of the head: give head landmarks in the sheet (e.g. the
nose bridge L27-L30 and the eye corners L36, L39, L42, L45).
"""

from __future__ import annotations

import re

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.recording import Recording

_LANDMARK = re.compile(r"^([XYZ])_(\d+)$")


def read_openface_csv(path, units: str | None = None) -> Recording:
    """Read the 3-D landmarks of an OpenFace 2.x CSV (see the module docstring); always mm."""
    import pandas as pd

    from facemotion.io.base import check_readable

    p = check_readable(path)
    try:
        df = pd.read_csv(p, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as e:
        raise InputError(f"{p}: cannot read as CSV ({str(e).splitlines()[0][:80]})") from None
    df.columns = [str(c).strip() for c in df.columns]
    for col in ("frame", "timestamp", "success"):
        if col not in df.columns:
            raise InputError(f"{p}: no {col!r} column; not an OpenFace 2.x landmark CSV")
    numbers: dict[str, set[int]] = {"X": set(), "Y": set(), "Z": set()}
    for col in df.columns:
        m = _LANDMARK.match(col)
        if m:
            numbers[m.group(1)].add(int(m.group(2)))
    if not numbers["X"]:
        raise InputError(f"{p}: no 3-D landmark columns X_0, Y_0, Z_0, ... (run OpenFace "
                         "with 3-D landmark output, -3Dfp)")
    n = max(numbers["X"]) + 1
    for axis in "XYZ":
        lacking = sorted(set(range(n)) - numbers[axis])
        if lacking:
            raise InputError(f"{p}: no column(s) {', '.join(f'{axis}_{k}' for k in lacking[:5])}")
    if df.empty:
        raise InputError(f"{p}: OpenFace CSV has no frames")
    if "face_id" in df.columns:
        faces = sorted(set(df["face_id"].str.strip()))
        if len(faces) > 1:
            raise InputError(f"{p}: several faces (face_id {', '.join(faces[:5])}); give one "
                             "face per file")

    def numeric(col: str) -> np.ndarray:
        try:
            return df[col].str.strip().astype(float).to_numpy()
        except ValueError:
            bad = next(k for k, v in enumerate(df[col]) if not _is_float(v))
            raise InputError(f"{p}: non-numeric value {token(df[col].iloc[bad])} in "
                             f"column {col!r} line {bad + 2}") from None

    frame, t, success = numeric("frame"), numeric("timestamp"), numeric("success")
    step_frames = np.diff(frame)
    if np.any(step_frames != 1):
        k = int(np.flatnonzero(step_frames != 1)[0])
        raise InputError(f"{p}: frame numbers jump from {frame[k]:g} to {frame[k + 1]:g} at "
                         f"line {k + 3}; frames must be consecutive")
    bad_success = ~np.isin(success, (0.0, 1.0))
    if bad_success.any():
        k = int(np.flatnonzero(bad_success)[0])
        raise InputError(f"{p}: success must be 0 or 1, got {success[k]:g} at line {k + 2}")
    if t.size < 2:
        raise InputError(f"{p}: need at least 2 frames to get the rate from 'timestamp'")
    if not np.isfinite(t).all():
        raise InputError(f"{p}: column 'timestamp' has non-finite values")
    # the step is the least-squares slope of timestamp on frame index (OpenFace writes
    # timestamps to the millisecond; the slope averages that rounding away)
    index = np.arange(t.size)
    step, origin = np.polyfit(index, t, 1)
    off = np.abs(t - (origin + step * index))
    if step <= 0 or off.max() > 0.25 * step:
        k = int(np.argmax(off))
        raise InputError(f"{p}: timestamps are not uniformly sampled (line {k + 2} is "
                         f"{off[k]:.4g} s off the grid of step {step:.6g} s; a dropped frame?)")
    rate = round(1.0 / step, 2)
    xyz = np.stack([np.stack([numeric(f"{a}_{k}") for a in "XYZ"], axis=1) for k in range(n)],
                   axis=1)  # (frames, landmarks, 3)
    xyz[success == 0] = np.nan
    # OpenFace writes its 3-D landmarks in mm: the format's own units win over the sheet's
    return Recording([f"L{k}" for k in range(n)], xyz, rate, source=str(p), units="mm",
                     units_source="file")


def _is_float(text) -> bool:
    try:
        float(str(text).strip())
    except ValueError:
        return False
    return True



def write_openface_csv(path, rec: Recording) -> None:
    """Write ``rec`` in the layout :func:`read_openface_csv` reads: ``frame`` (1-based),
    ``face_id`` 0, ``timestamp`` (s), ``confidence`` 1, ``success`` 1, then ``X_i``, ``Y_i``,
    ``Z_i`` (mm) with landmark i = ``rec.labels[i]`` (read back as ``L{i}``). OpenFace reports
    every landmark of a frame or none, so a take with a missing sample is refused (one line
    naming the marker and frame) instead of being written in a way OpenFace never writes."""
    from facemotion.io.atomic import atomic_path
    from facemotion.io.base import format_coordinate

    missing = ~np.isfinite(rec.points).all(axis=2)
    if missing.any():
        f, j = (int(x) for x in np.argwhere(missing)[0])
        raise InputError(f"{rec.source or 'recording'}: marker {rec.labels[j]!r} is missing at "
                         f"frame {f + 1}; an OpenFace CSV has every landmark of a tracked "
                         "frame (write TRC or C3D instead)")
    n = rec.n_markers
    header = ["frame", "face_id", "timestamp", "confidence", "success"]
    header += [f"{a}_{k}" for a in "XYZ" for k in range(n)]
    flat = rec.points.transpose(0, 2, 1).reshape(rec.n_frames, 3 * n)  # X..., Y..., Z...
    out = [", ".join(header)]
    for f in range(rec.n_frames):
        out.append(f"{f + 1}, 0, {f / rec.rate:.6f}, 1, 1, "
                   + ", ".join(format_coordinate(x) for x in flat[f]))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
