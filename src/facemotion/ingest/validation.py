"""What every take must satisfy before it enters the analysis (the loading boundary).

The readers check that a file is what it says it is (layout, frame count, fields). This module
checks that what it says is plausible for a recording of a face, because a file can be
well-formed and still give a plausible wrong number:

* **Units.** A file's own units win over the subject sheet's; a sheet that disagrees is
  reported (:func:`units_conflict`). The markers of a face lie 10-300 mm (the setting
  ``checks.face_spread_mm``) from their centre (median over markers and frames; measured
  41-63 mm on the shared AnimFace and GRID data): a spread outside that range means the
  declared units are wrong (a CSV in metres read as millimetres, a TRC header saying ``m`` for
  millimetre data) and stops the run, naming the units and the spread measured
  (:func:`check_face_spread`); when no other metric unit would bring the spread into that
  range (a body, a capture volume), the take is refused as not a face.
* **Length and rate.** A take shorter than ``checks.min_take_frames`` frames is an error,
  training and held out alike (a one-frame take has no motion: its error curve is all zeros);
  so is a frame rate outside ``checks.rate_hz`` (10-2000 Hz; a time column in milliseconds).
* **One face.** Every take must show the first take's face (:func:`check_same_shape`): its
  best frame must fit the first take's median marker positions by a rigid motion to within
  ``checks.max_shape_rms_mm`` (20 mm RMS; 1-s windows of the AnimFace jaw exercise, mouth held
  open, reach 9.7 mm, the takes of one subject 1.5 mm), and a take that fits much better with
  a reflection has its axes swapped or mirrored.
* **Physical plausibility** (:func:`find_outliers`). A sample farther than
  ``gaps.max_distance_mm`` from the face's centre in its frame (the median of the markers'
  positions), or reached by a jump faster than ``gaps.max_speed_mm_s`` from the marker's
  neighbouring samples, is an outlier: a corrupt value (1e30, a flipped bit), a marker swap or
  a tracker jump. Outliers go in the gap report and the log; they are treated as gaps
  (removed, then filled and flagged like any missing sample; ``gaps.outliers: gaps``, the
  default) or stop the run (``gaps.outliers: error``). A take more than half outliers stops
  the run either way, and so does a take in which no marker moves at all (a frozen or
  placeholder take: its error curve would be zeros).

A jump faster than the limit splits a marker's trajectory into pieces; the longest piece is
taken as the marker and the samples of every other piece are outliers. An isolated spike is
a piece of one sample; a stretch during which the tracker followed another point is a short
piece between two jumps.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from facemotion.errors import InputError
from facemotion.ingest.gaps import runs
from facemotion.io.base import unit_scale
from facemotion.io.recording import Recording, finite_samples

log = logging.getLogger("facemotion")

OUTLIER_MODES = ("gaps", "error")
MAX_OUTLIER_FRACTION = 0.5  # a take more than half outliers would be reconstructed, not measured


@dataclass(frozen=True)
class Limits:
    """The plausibility limits (settings ``gaps.*`` and ``checks.*``; defaults in docs/settings.md).

    ``names``: what a message calls each limit, by field. By default the argument
    (``limits.face_spread_mm``); the study passes its settings (``setting checks.face_spread_mm``).
    """

    max_distance_mm: float = 250.0
    max_speed_mm_s: float = 1000.0
    outliers: str = "gaps"
    min_take_frames: int = 10
    face_spread_mm: tuple[float, float] = (10.0, 300.0)
    rate_hz: tuple[float, float] = (10.0, 2000.0)
    max_shape_rms_mm: float = 20.0
    names: Mapping[str, str] = field(default_factory=dict, compare=False, repr=False)

    def name(self, limit: str) -> str:
        return self.names.get(limit, f"limits.{limit}")

    def __post_init__(self) -> None:
        if self.outliers not in OUTLIER_MODES:
            raise InputError(f"{self.name('outliers')}: must be one of {', '.join(OUTLIER_MODES)}"
                             f", got {self.outliers!r}")
        if not (np.isfinite(self.max_distance_mm) and self.max_distance_mm > 0):
            raise InputError(f"{self.name('max_distance_mm')}: must be positive, got "
                             f"{self.max_distance_mm!r}")
        if not (np.isfinite(self.max_speed_mm_s) and self.max_speed_mm_s > 0):
            raise InputError(f"{self.name('max_speed_mm_s')}: must be positive, got "
                             f"{self.max_speed_mm_s!r}")
        lo, hi = self.face_spread_mm
        if not 0 < lo < hi:
            raise InputError(f"{self.name('face_spread_mm')}: need 0 < low < high, got "
                             f"{list(self.face_spread_mm)}")
        lo, hi = self.rate_hz
        if not 0 < lo < hi:
            raise InputError(f"{self.name('rate_hz')}: need 0 < low < high, got "
                             f"{list(self.rate_hz)}")
        if not (np.isfinite(self.max_shape_rms_mm) and self.max_shape_rms_mm > 0):
            raise InputError(f"{self.name('max_shape_rms_mm')}: must be positive, got "
                             f"{self.max_shape_rms_mm!r}")
        if int(self.min_take_frames) < 2:
            raise InputError(f"{self.name('min_take_frames')}: must be at least 2, got "
                             f"{self.min_take_frames!r}")


@dataclass
class TakeCheck:
    """What the checks found in one take."""

    outliers: np.ndarray        # (frames, markers) bool
    units: str                  # the units the file's numbers were read in
    units_source: str           # "file", "sheet" or "default"
    units_conflict: str         # "" or what the sheet said instead
    spread_mm: float            # median distance of the markers to their centroid


def units_conflict(rec: Recording, sheet_units: str | None) -> str:
    """'' or a note when the sheet's units differ from those the file states (the file wins)."""
    if sheet_units is None or rec.units_source != "file":
        return ""
    where = rec.source or "recording"
    if unit_scale(sheet_units, where) == unit_scale(rec.units, where):
        return ""
    return f"sheet says {sheet_units}"


def _nanmedian_markers(x: np.ndarray) -> np.ndarray:
    """np.nanmedian(x, axis=1, keepdims=True) for (frames, markers[, 3]) by one sort (NaN sort
    last) and the middle of each slice's measured values: numpy's nanmedian takes a masked-array
    path along a short axis (measured 3-8x slower on 4,000 frames x 468 markers x 3)."""
    s = np.sort(x, axis=1)
    c = np.count_nonzero(~np.isnan(x), axis=1, keepdims=True)
    lo = np.take_along_axis(s, np.maximum(c - 1, 0) // 2, axis=1)
    hi = np.take_along_axis(s, np.maximum(c, 1) // 2 - (c == 0), axis=1)
    with np.errstate(invalid="ignore"):
        m = (lo + hi) / 2.0
    return np.where(c > 0, m, np.nan)


#: Frames per block of the validation's passes (bounds their temporary memory).
BLOCK_FRAMES = 2048


def _median_full(p: np.ndarray) -> np.ndarray:
    """np.median(p, axis=1, keepdims=True) of values without NaN, by one partition: for an
    even count the lower middle value is the largest of those below the upper one (numpy's
    median partitions at both; the same two values, the same mean)."""
    if p.shape[1] == 0:
        return np.median(p, axis=1, keepdims=True)
    h = p.shape[1] // 2
    x = np.partition(p, h, axis=1)
    upper = x[:, h:h + 1]
    if p.shape[1] % 2:
        return upper
    return (x[:, :h].max(axis=1, keepdims=True) + upper) / 2.0


def _median_markers(p: np.ndarray) -> np.ndarray:
    """Per-frame median over the markers (axis 1, keepdims) of (frames, markers[, 3]), NaN
    for missing: numpy's partition-based median on the frames measured in full (the common
    case), :func:`_nanmedian_markers` on the others. Same values as np.nanmedian."""
    full = ~np.isnan(p).reshape(len(p), -1).any(axis=1)
    if full.all():
        return _median_full(p)
    out = np.empty((len(p), 1) + p.shape[2:])
    if full.any():
        out[full] = _median_full(p[full])
    out[~full] = _nanmedian_markers(p[~full])
    return out


def centre_distances(rec: Recording, ok: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(frames, markers) distance (mm) of every sample to its frame's face centre (the
    per-axis median of the markers measured in that frame; a robust centroid: one corrupt
    sample of 1e30 mm does not move it), NaN where the sample is missing or the frame has
    fewer than 3 markers measured; and the (frames,) mask of frames with 3 or more.
    Computed in blocks of ``BLOCK_FRAMES`` frames. ``ok``: ``finite_samples(rec.points)``
    when the caller has it."""
    pts = rec.points
    F, n, _ = pts.shape
    dist = np.empty((F, n))
    enough = np.zeros(F, dtype=bool)
    for a in range(0, F, BLOCK_FRAMES):
        blk = pts[a:a + BLOCK_FRAMES]
        b = a + len(blk)
        okb = finite_samples(blk) if ok is None else ok[a:b]
        enough[a:b] = okb.sum(axis=1) >= 3
        e = np.flatnonzero(enough[a:b])
        if e.size < len(blk):
            dist[a:b] = np.nan
        if e.size == 0:
            continue
        full = e.size == len(blk)
        p = blk if full else blk[e]
        oke = okb if full else okb[e]
        if not oke.all():
            p = np.where(oke[:, :, None], p, np.nan)
        with np.errstate(invalid="ignore", over="ignore"):
            d = p - _median_markers(p)
            r = np.sqrt(np.einsum("fnc,fnc->fn", d, d))
        if full:
            dist[a:b] = r
        else:
            dist[a + e] = r
    return dist, enough


def face_spread(rec: Recording, distances: tuple[np.ndarray, np.ndarray] | None = None
                ) -> float:
    """Median over frames of the median distance (mm) of the markers to their centre.

    The centre is the per-axis median of the markers (a robust centroid: one corrupt sample
    of 1e30 mm does not move it), over frames with at least 3 markers measured.
    ``distances``: :func:`centre_distances` of ``rec`` when already computed.
    """
    dist, enough = centre_distances(rec) if distances is None else distances
    if not enough.any():
        return float("nan")
    return float(np.median(_median_markers(dist[enough])[:, 0]))


def check_face_spread(rec: Recording, limits: Limits,
                      distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The spread of the face (:func:`face_spread`); InputError if outside the limits."""
    return check_spread_value(face_spread(rec, distances), rec, limits)


def check_spread_value(spread: float, rec, limits: Limits) -> float:
    """A spread (:func:`face_spread`, however computed) checked against the limits; ``rec``
    gives the source and units named in the message."""
    lo, hi = limits.face_spread_mm
    where = rec.source or "recording"
    if not np.isfinite(spread):
        raise InputError(f"{where}: no frame has 3 or more markers measured")
    if not lo <= spread <= hi:
        declared = {"file": "as the file declares", "sheet": "as the subject sheet says",
                    "default": "the default for a file that does not say"}[rec.units_source]
        fits = _units_that_fit(spread, rec.units, (lo, hi))
        if not fits:
            raise InputError(
                f"{where}: not a face: the markers span a median {spread:.3g} mm from their "
                f"centre (read in {rec.units}, {declared}), where a face spans {lo:g}-{hi:g} mm "
                f"({limits.name('face_spread_mm')}), and no other metric units "
                f"({', '.join(_METRIC)}) would bring them there")
        raise InputError(
            f"{where}: the markers lie a median {spread:.3g} mm from their centre when "
            f"read in {rec.units} ({declared}); a face spans {lo:g}-{hi:g} mm "
            f"({limits.name('face_spread_mm')}): the units are wrong ({' or '.join(fits)} "
            f"would fit), fix the {'file' if rec.units_source == 'file' else 'sheet'}'s units")
    return spread


#: The units a face's spread is tried in when it is off: a file or sheet that names the wrong
#: metric unit (a factor of 10, 100 or 1000) is the common mistake; an inch/metre mix-up is not.
_METRIC = ("mm", "cm", "m")


def _units_that_fit(spread: float, used: str, limits: tuple[float, float]) -> list[str]:
    """The metric units (other than ``used``) in which a spread of ``spread`` mm, read in
    ``used``, would lie within ``limits``."""
    lo, hi = limits
    scale = unit_scale(used, "units")
    return [u for u in _METRIC if unit_scale(u, "units") != scale
            and lo <= spread * unit_scale(u, "units") / scale <= hi]


def check_rate(rec: Recording, limits: Limits) -> None:
    """A frame rate outside ``checks.rate_hz`` is an error (a CSV time column in ms gives a
    rate 1000 times too low, a TRC DataRate typed wrong one that is off by the same)."""
    lo, hi = limits.rate_hz
    if not lo <= rec.rate <= hi:
        raise InputError(f"{rec.source or 'recording'}: frame rate {rec.rate:g} Hz is outside "
                         f"{lo:g}-{hi:g} Hz ({limits.name('rate_hz')}): is the time column in "
                         "seconds and the rate in Hz?")


def _fit_rms(X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RMS residuals (B,) of the best fits of X (B, m, 3) onto Y (m, 3) by rotation and
    translation, and by rotation, reflection and translation (Kabsch; Procrustes), from one
    SVD of each cross-covariance."""
    Xc = X - X.mean(axis=1, keepdims=True)
    Yc = Y - Y.mean(axis=0)
    U, S, Vt = np.linalg.svd(np.einsum("bmi,mj->bij", Xc, Yc))
    # no reflection: flip the smallest singular value's sign when det(U V^T) < 0
    d = np.sign(np.linalg.det(U @ Vt))
    S_proper = S.copy()
    S_proper[:, 2] *= np.where(d == 0, 1.0, d)
    base = np.sum(Xc ** 2, axis=(1, 2)) + np.sum(Yc ** 2)
    return tuple(np.sqrt(np.maximum(base - 2 * s.sum(axis=1), 0.0) / X.shape[1])
                 for s in (S_proper, S))


def check_same_shape(recs: list[Recording], limits: Limits, max_frames: int = 200
                     ) -> list[float]:
    """Each take's face against the first take's (the median position of its markers).

    For up to ``max_frames`` frames of a take, the face is fitted onto the reference by a
    rigid motion; the best frame's RMS residual must be within ``checks.max_shape_rms_mm``.
    A take that fits much better with a reflection than without has its axes swapped or
    mirrored (an error whatever the limit). Returns the RMS of each take (0 for the first).
    """
    with warnings.catch_warnings():   # a marker never seen is NaN here; gaps.py names it
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = np.nanmedian(np.where(np.isfinite(recs[0].points), recs[0].points, np.nan),
                           axis=0)
    out = [0.0]
    cols = finite_samples(ref)
    idx = np.flatnonzero(cols)
    for rec in recs[1:]:
        where = rec.source or "recording"
        frames = np.flatnonzero(finite_samples(rec.points)[:, cols].all(axis=1))
        if idx.size < 3 or frames.size == 0:
            out.append(float("nan"))
            continue
        frames = frames[np.linspace(0, frames.size - 1, min(frames.size, max_frames)).astype(int)]
        X = rec.points[frames][:, cols]  # (this layout: the sums, so the RMS, as before)
        proper, mirror = (float(np.min(r)) for r in _fit_rms(X, ref[cols]))
        shape_verdict(proper, mirror, where, recs[0].source, limits)
        out.append(proper)
    return out


def check_moves(rec: Recording) -> None:
    """InputError if no marker of the take ever leaves its first measured position."""
    pts = rec.points
    ok = finite_samples(pts)
    first = np.argmax(ok, axis=0)  # each marker's first measured frame
    ref = pts[first, np.arange(rec.n_markers)]
    with np.errstate(invalid="ignore"):
        moved = np.any(ok & (pts != ref[None]).any(axis=2))
    if ok.any() and not moved:
        raise InputError(f"{rec.source or 'recording'}: no marker moves in this take (every "
                         "sample equals the marker's first): a frozen or placeholder take")


def check_take_length(rec: Recording, limits: Limits, role: str = "") -> None:
    if rec.n_frames < limits.min_take_frames:
        raise InputError(f"{rec.source or 'recording'}: {role + ' ' if role else ''}take has "
                         f"{rec.n_frames} frame(s), fewer than the minimum "
                         f"{limits.min_take_frames} ({limits.name('min_take_frames')})")


def _reachable(x: np.ndarray, frames: np.ndarray, rate: float, vmax: float) -> np.ndarray:
    """Which samples x (m, 3) at ``frames`` belong to one physically possible trajectory.

    Jumps faster than ``vmax`` split the samples into pieces. The longest piece is kept; going
    outwards from it, a piece is kept when it can be reached from the nearest kept sample at
    no more than ``vmax`` (over the time between them), so that an isolated spike is dropped but
    the samples after it are kept, and a step that lasts is dropped in full.
    """
    speed = np.linalg.norm(np.diff(x, axis=0), axis=1) * rate / np.diff(frames)
    cuts = np.flatnonzero(~(speed <= vmax))
    keep = np.ones(len(x), dtype=bool)
    if cuts.size == 0:
        return keep
    bounds = np.concatenate([[0], cuts + 1, [len(x)]])
    pieces = list(zip(bounds[:-1], bounds[1:], strict=True))
    anchor = int(np.argmax([b - a for a, b in pieces]))
    keep[:] = False
    a, b = pieces[anchor]
    keep[a:b] = True

    def fits(i: int, k: int) -> bool:
        v = np.linalg.norm(x[i] - x[k]) * rate / abs(frames[i] - frames[k])
        return bool(v <= vmax)

    last = b - 1
    for a, b in pieces[anchor + 1:]:
        if fits(a, last):
            keep[a:b] = True
            last = b - 1
    first = pieces[anchor][0]
    for a, b in reversed(pieces[:anchor]):
        if fits(b - 1, first):
            keep[a:b] = True
            first = a
    return keep


def _fast_markers(pts: np.ndarray, valid: np.ndarray, rate: float, vmax: float) -> np.ndarray:
    """(markers,) True for the markers that need :func:`_reachable`: a sample not valid
    (missing or far: the speed across it is checked sample to sample) or a step between
    consecutive frames faster than ``vmax``. Vectorised over markers, in blocks of frames."""
    F = len(pts)
    need = ~valid.all(axis=0)
    for a in range(0, F - 1, BLOCK_FRAMES):
        b = min(F, a + BLOCK_FRAMES + 1)
        d = np.diff(pts[a:b], axis=0)
        with np.errstate(invalid="ignore", over="ignore"):
            step = np.sqrt(np.einsum("fnc,fnc->fn", d, d)) * rate
        need |= (step > vmax).any(axis=0)
    return need


def find_outliers(rec: Recording, limits: Limits,
                  distances: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, list[str]]:
    """(frames, markers) mask of implausible samples, and one note per affected marker.

    ``distances``: :func:`centre_distances` of ``rec`` when already computed."""
    pts = np.asarray(rec.points, dtype=float)
    F, n, _ = pts.shape
    ok = finite_samples(pts)
    out = np.zeros((F, n), dtype=bool)
    # distance from the face centre: the per-axis median of the markers measured in the frame
    dist, _ = centre_distances(rec) if distances is None else distances
    dist = np.nan_to_num(dist, nan=0.0)
    far = dist > limits.max_distance_mm
    out |= far
    fast = np.zeros((F, n), dtype=bool)
    top_speed = np.zeros(n)
    # only markers with a gap, a far sample or a fast step need the piecewise test
    for j in np.flatnonzero(_fast_markers(pts, ok & ~far, rec.rate, limits.max_speed_mm_s)):
        idx = np.flatnonzero(ok[:, j] & ~far[:, j])
        if idx.size >= 2:
            keep = _reachable(pts[idx, j], idx, rec.rate, limits.max_speed_mm_s)
            fast[idx[~keep], j] = True
            if not keep.all():
                with np.errstate(invalid="ignore", over="ignore"):
                    v = np.linalg.norm(np.diff(pts[idx, j], axis=0), axis=1) * rec.rate \
                        / np.diff(idx)
                top_speed[j] = float(np.nanmax(v))
    out |= fast
    notes = outlier_notes(out, far, fast, dist.max(axis=0), top_speed, rec.labels, rec.rate,
                          limits)
    return out, notes


def outlier_notes(out, far, fast, far_max, top_speed, labels, rate, limits) -> list[str]:
    """One note per marker with outliers (frames x markers masks ``out``, ``far``, ``fast``):
    how many, in how many runs, the first, and why (the largest distance from the face centre
    ``far_max`` and speed ``top_speed`` per marker)."""

    notes = []
    for j in np.flatnonzero(out.any(axis=0)):
        first = int(np.flatnonzero(out[:, j])[0])
        why = []
        if far[:, j].any():
            why.append(f"{int(far[:, j].sum())} at up to {far_max[j]:.3g} mm from the face "
                       f"centre (limit {limits.max_distance_mm:g} mm, "
                       f"{limits.name('max_distance_mm')})")
        if fast[:, j].any():
            why.append(f"{int(fast[:, j].sum())} reached at up to {top_speed[j]:.3g} mm/s "
                       f"(limit {limits.max_speed_mm_s:g} mm/s, {limits.name('max_speed_mm_s')})")
        notes.append(f"marker {labels[j]!r}: {int(out[:, j].sum())} outlier sample(s) in "
                     f"{len(runs(out[:, j]))} run(s), first at frame {first + 1} "
                     f"(t = {first / rate:.3f} s): {'; '.join(why)}")
    return notes


def shape_verdict(proper: float, mirror: float, where: str, first: str,
                  limits: Limits) -> None:
    """A take's face against the first take's (``first``), by the RMS of the best rigid fit
    without (``proper``) and with (``mirror``) a reflection: a mirror image, or a face too
    different, is an error."""
    if mirror < 0.5 * proper:
        raise InputError(f"{where}: the face is a mirror image of {first}'s "
                         f"(it fits it to {mirror:.3g} mm RMS with a reflection, "
                         f"{proper:.3g} mm without): two axes swapped or one negated?")
    if proper > limits.max_shape_rms_mm:
        raise InputError(
            f"{where}: the face differs from {first}'s by {proper:.3g} mm RMS at "
            f"best after a rigid fit (limit {limits.max_shape_rms_mm:g} mm, "
            f"{limits.name('max_shape_rms_mm')}): markers relabelled, or another face?")


def check_header(rec, limits: Limits, sheet_units: str | None = None, role: str = ""):
    """The checks a take's header decides (units against the sheet's: a warning, and the
    conflict returned; length and rate: InputError); ``rec`` needs only source, rate,
    n_frames, units, units_source."""
    conflict = units_conflict(rec, sheet_units)
    if conflict:
        log.warning("%s: the file declares %s, the subject sheet %s: the file's units are "
                    "used", rec.source or "recording", rec.units, sheet_units)
    check_take_length(rec, limits, role)
    check_rate(rec, limits)
    return conflict


def check_take(rec: Recording, limits: Limits, sheet_units: str | None = None,
               role: str = "") -> tuple[Recording, TakeCheck]:
    """All the checks of one take; returns the take with its outliers removed (NaN) and what
    was found. InputError on wrong units, a short take, or outliers with outliers: error."""
    where = rec.source or "recording"
    conflict = check_header(rec, limits, sheet_units, role)
    distances = centre_distances(rec)  # once, for the units and the outliers
    spread = check_face_spread(rec, limits, distances)
    mask, notes = find_outliers(rec, limits, distances)
    check_moves(rec)
    measured = finite_samples(rec.points).sum()
    if measured and mask.sum() > MAX_OUTLIER_FRACTION * measured:
        raise InputError(f"{where}: {mask.sum()} of the take's {measured} measured samples are "
                         f"outliers (more than {MAX_OUTLIER_FRACTION:.0%}; first: {notes[0]})")
    if notes:
        if limits.outliers == "error":
            raise InputError(f"{where}: {notes[0]} ({limits.name('outliers')} is 'error')")
        for note in notes:
            log.warning("%s: %s; treated as gaps", where, note)
    if mask.any():  # the caller's take is left as it was
        pts = rec.points.copy()
        pts[mask] = np.nan
        clean = Recording(list(rec.labels), pts, rec.rate, rec.source, rec.filled.copy(),
                          rec.units, rec.units_source)
    else:
        clean = rec
    return clean, TakeCheck(mask, rec.units, rec.units_source, conflict, spread)


def margins(rec: Recording) -> dict:
    """What the limits are compared with, measured on one take: the fastest frame-to-frame
    speed, the largest distance to the face centre, the spread (for choosing the defaults)."""
    pts = rec.points
    with np.errstate(invalid="ignore"):
        speed = np.linalg.norm(np.diff(pts, axis=0), axis=2) * rec.rate
        centre = np.nanmedian(pts, axis=1, keepdims=True)
        dist = np.linalg.norm(pts - centre, axis=2)
    return {"rate_hz": rec.rate, "frames": rec.n_frames, "markers": rec.n_markers,
            "max_speed_mm_s": float(np.nanmax(speed)) if speed.size else float("nan"),
            "max_distance_mm": float(np.nanmax(dist)), "spread_mm": face_spread(rec),
            "outliers": int(find_outliers(rec, Limits())[0].sum())}


if __name__ == "__main__":  # python -m facemotion.ingest.validation FILE... : the margins per file
    import sys

    from facemotion.io.registry import read_recording

    print("file\trate_hz\tframes\tmarkers\tmax_speed_mm_s\tmax_distance_mm\tspread_mm\t"
          "outliers")
    for arg in sys.argv[1:]:
        try:
            m = margins(read_recording(arg, arg.rsplit(".", 1)[-1]))
        except InputError as exc:
            sys.exit(f"facemotion: {exc}")
        print(f"{arg.rsplit('/', 1)[-1]}\t{m['rate_hz']:g}\t{m['frames']}\t{m['markers']}\t"
              f"{m['max_speed_mm_s']:.0f}\t{m['max_distance_mm']:.0f}\t{m['spread_mm']:.1f}\t"
              f"{m['outliers']}")
