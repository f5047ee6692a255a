"""OpenFace 2.x landmark CSV (FeatureExtraction / FaceLandmarkVid output).

Layout (OpenFace wiki, "Output Format"): one row per video frame with columns ``frame``
(1-based), ``face_id`` (not in older versions), ``timestamp`` (s), ``confidence``, ``success``,
..., the 2-D landmarks ``x_0 .. x_67``, ``y_0 .. y_67`` (pixels) and the 3-D landmarks ``X_0 ..
X_67``, ``Y_0 ..``, ``Z_0 ..`` in millimetres in the camera's frame; column names may have a
leading space. Older versions end the last row without a line end.

The 3-D landmarks are read as markers ``L0 .. L67`` (OpenFace's landmark numbers), in mm. Every
row must have the header's number of fields, and the frame numbers must step by 1 (a row
removed, repeated or swapped is an error naming the line). A frame with ``success`` 0 (no face
tracked) or with ``confidence`` below ``min_confidence`` is a missing sample of every landmark:
a gap, counted in the gap report like any other.

The rate is the declared one (the sheet's ``rate``, ``--rate``) when given; else 1 / the step
of ``timestamp`` (least-squares slope, rounded to 0.01 Hz), which must be uniform (no timestamp
further than a quarter step from the fitted grid). Time stamps can be wrong (an image sequence
read without its frame rate steps by 1 ms): when the landmarks would move implausibly fast at
the rate the time stamps imply, the file is refused with a line saying so and how to declare
the rate. Camera coordinates include the motion of the head: give head landmarks in the sheet
(e.g. the nose bridge L27-L30 and the eye corners L36, L39, L42, L45).
"""

from __future__ import annotations

import csv
import logging
import re

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.checks import check_field_counts, check_frame_numbers
from facemotion.io.recording import Recording

log = logging.getLogger("facemotion")
_LANDMARK = re.compile(r"^([XYZ])_(\d+)$")

#: Frames whose ``confidence`` is below this are gaps. OpenFace documents ``confidence`` as its
#: tracker's certainty in [0, 1] and sets ``success`` from its own cut-off, which keeps frames
#: of a track that is drifting; below 0.5 the tracker rates its landmarks more likely wrong than
#: right, while a tracked face scores near 0.9 (0.88-0.98 in the vendor suite's file).
OPENFACE_MIN_CONFIDENCE = 0.5

#: A face whose landmarks move, in the median over landmarks and frames, faster than this
#: (mm/s) at the rate the time stamps imply is not moving as a face does: the fastest
#: articulators (the lips, the jaw) peak at a few hundred mm/s in speech, and most landmarks
#: of a talking face are far slower. Such a file's time stamps are taken as wrong.
FACE_MAX_MEDIAN_SPEED_MM_S = 500.0


def read_openface_csv(path, units: str | None = None, rate: float | None = None,
                      min_confidence: float = OPENFACE_MIN_CONFIDENCE) -> Recording:
    """Read the 3-D landmarks of an OpenFace 2.x CSV (see the module docstring); always mm.

    rate: the declared frame rate (Hz), which replaces the time stamps' rate."""
    from facemotion.io.base import check_readable

    p = check_readable(path)
    header, rows, numbers = _openface_rows(p)
    where, n = _openface_columns(p, header)
    check_field_counts(p, numbers, [len(r) for r in rows], len(header), "the header line")
    if "face_id" in where:
        faces = sorted({r[where["face_id"]].strip() for r in rows})
        if len(faces) > 1:
            raise InputError(f"{p}: several faces (face_id {', '.join(faces[:5])}); give one "
                             "face per file")
    frame, t, success = (_column(p, rows, numbers, where[c], c)
                         for c in ("frame", "timestamp", "success"))
    check_openface_block(p, numbers, frame, success)
    if rate is None:
        rate = timestamp_rate(p, numbers, t)
        declared = False
    else:
        declared = True
        log.info("%s: rate %g Hz as declared (the time stamps are not used)", p, rate)
    xyz = np.stack([np.stack([_column(p, rows, numbers, where[f"{a}_{k}"], f"{a}_{k}")
                              for a in "XYZ"], axis=1) for k in range(n)], axis=1)
    gaps = success == 0
    if "confidence" in where:
        low = _column(p, rows, numbers, where["confidence"], "confidence") < min_confidence
        if (low & ~gaps).any():
            log.info("%s: %d frame(s) with confidence below %g are gaps", p,
                     int((low & ~gaps).sum()), min_confidence)
        gaps |= low
    xyz[gaps] = np.nan
    if not declared:
        check_face_speed(p, xyz, rate)
    # OpenFace writes its 3-D landmarks in mm: the format's own units win over the sheet's
    return Recording([f"L{k}" for k in range(n)], xyz, rate, source=str(p), units="mm",
                     units_source="file")


def read_openface_labels(path) -> list[str]:
    """The landmark labels (L0, L1, ...) from the header line alone."""
    from facemotion.io.base import check_readable

    p = check_readable(path)
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            first = next(csv.reader(fh), None)
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise InputError(f"{p}: cannot read as OpenFace CSV text ({type(e).__name__})") from None
    if not first:
        raise InputError(f"{p}: OpenFace CSV is empty")
    _, n = _openface_columns(p, [c.strip() for c in first])
    return [f"L{k}" for k in range(n)]


def _openface_rows(p) -> tuple[list[str], list[list[str]], list[int]]:
    """The header's column names (stripped) and the non-blank data rows with line numbers."""
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            table = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise InputError(f"{p}: cannot read as OpenFace CSV text ({type(e).__name__})") from None
    if not table or not table[0]:
        raise InputError(f"{p}: OpenFace CSV is empty")
    header = [c.strip() for c in table[0]]
    rows, numbers = [], []
    for i, r in enumerate(table[1:], start=2):
        if any(c.strip() for c in r):
            rows.append(r)
            numbers.append(i)
    if not rows:
        raise InputError(f"{p}: OpenFace CSV has no frames")
    return header, rows, numbers


def _openface_columns(p, header: list[str]) -> tuple[dict[str, int], int]:
    """Column index of each name, and the number of 3-D landmarks (every X, Y, Z present)."""
    where = {c: j for j, c in enumerate(header)}
    for col in ("frame", "timestamp", "success"):
        if col not in where:
            raise InputError(f"{p}: no {col!r} column; not an OpenFace 2.x landmark CSV")
    numbers: dict[str, set[int]] = {"X": set(), "Y": set(), "Z": set()}
    for col in header:
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
    return where, n


def _column(p, rows, numbers, j: int, name: str) -> np.ndarray:
    """Column ``j`` of every row as floats; InputError naming the line of a non-number."""
    try:
        return np.array([float(r[j]) for r in rows])
    except ValueError:
        k = next(k for k, r in enumerate(rows) if not _is_float(r[j]))
        raise InputError(f"{p}: non-numeric value {token(rows[k][j])} in column {name!r} "
                         f"line {numbers[k]}") from None


def check_openface_block(p, numbers, frame, success, previous_frame: float | None = None
                         ) -> None:
    """A block of rows: frame numbers step by 1 (from ``previous_frame``), success 0 or 1."""
    check_frame_numbers(p, numbers, frame, previous_frame, column="frame")
    bad = np.flatnonzero(~np.isin(success, (0.0, 1.0)))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{p}: success must be 0 or 1, got {success[k]:g} at line "
                         f"{numbers[k]}")


def timestamp_rate(p, numbers, t: np.ndarray) -> float:
    """The rate of uniformly stepping time stamps (see the module docstring)."""
    if t.size < 2:
        raise InputError(f"{p}: need at least 2 frames to get the rate from 'timestamp' "
                         "(or declare the rate)")
    if not np.isfinite(t).all():
        raise InputError(f"{p}: column 'timestamp' has non-finite values")
    # the step is the least-squares slope of timestamp on frame index (OpenFace writes
    # timestamps to the millisecond; the slope averages that rounding away)
    index = np.arange(t.size)
    step, origin = np.polyfit(index, t, 1)
    off = np.abs(t - (origin + step * index))
    if step <= 0 or off.max() > 0.25 * step:
        k = int(np.argmax(off))
        raise InputError(f"{p}: timestamps are not uniformly sampled (line {numbers[k]} is "
                         f"{off[k]:.4g} s off the grid of step {step:.6g} s; a dropped frame?)")
    return round(1.0 / step, 2)


def check_face_speed(p, xyz: np.ndarray, rate: float) -> None:
    """InputError when, at ``rate``, the landmarks' median speed is not a face's (see
    ``FACE_MAX_MEDIAN_SPEED_MM_S``): the time stamps, not the face, are then wrong."""
    step = np.linalg.norm(np.diff(xyz, axis=0), axis=2)
    step = step[np.isfinite(step)]
    if step.size == 0:
        return
    speed = float(np.median(step)) * rate
    if speed > FACE_MAX_MEDIAN_SPEED_MM_S:
        raise InputError(
            f"{p}: at the {rate:g} Hz its timestamps imply (a step of {1000.0 / rate:.4g} ms), "
            f"the landmarks move at a median {speed:.0f} mm/s, implausibly fast for a face "
            f"(over {FACE_MAX_MEDIAN_SPEED_MM_S:g} mm/s): the timestamps are wrong; declare the "
            "video's frame rate (the sheet's rate column, or --rate)")


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
