"""Gap report and gap filling of marker trajectories.

A sample is missing when any of its coordinates is NaN; gaps are runs of missing samples.

* Short interior gaps (at most ``max_interp_s`` seconds, with measured samples on both sides)
  are filled by a cubic spline (scipy ``CubicSpline``, not-a-knot) through all the marker's
  measured samples, evaluated in the gap.
* Longer gaps, and gaps at the start or end of a take (which cannot be interpolated), go to the
  long-gap method. ``"pca"`` reconstructs them from the other markers' correlated motion, in
  the manner of Gloersen & Federolf (2016, J. Biomech. 49:1180), one gap at a time: the donor
  markers are those measured throughout the gap; the frames x 3(d + 1) matrix of the donors
  and the gap's marker over the frames where all of them are measured is centred (mean mu)
  and its PCA gives directions V (k components for 99.9 % of the variance, at most 3d); in
  the gap the donors' coordinates fit the scores, z = argmin |V_d z - (x_d - mu_d)|, and the
  marker is x_j = mu_j + V_j z. Filled values of other markers are never used as donors, so
  the result does not depend on the order of the gaps, and no frame needs every marker.
  A gap with no donor, or fewer than ``MIN_COMPLETE`` frames to learn from, is an
  InputError. ``"error"`` raises an InputError naming the marker and the first long gap.

Accuracy (checked in tests/test_gaps.py):

* cubic: the error in a gap spanning h seconds between measured samples stays within
  1.25 x the cubic Hermite bound h^4/384 * max|f''''| (measured up to 1.12 x on sinusoids).
  At 120 Hz a 0.1 s gap (12 frames, h = 13/120 s) of a 5 mm sinusoid gives max error
  < 0.06 mm at 2 Hz (measured 0.050), < 0.004 mm at 1 Hz, but about 1.6 mm at 5 Hz (half a
  cycle missing): for 5 Hz motion to stay under 0.05 mm use max_interp_s <= 0.035 s.
* pca, 20 markers driven by 3 smooth sources plus 0.05 mm noise, three gaps of 0.5-1 s in
  10 s (one at the start of the take): RMS error < 0.1 mm (about the noise), max < 0.4 mm,
  for motion of about 6 mm RMS; also when no frame has every marker: RMS < 0.2 mm.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from facemotion.errors import InputError
from facemotion.recording import Recording

REPORT_COLUMNS = ["marker", "frames", "missing_frames", "missing_fraction",
                  "longest_gap_frames", "n_gaps", "filled_frames", "fill_method"]
LONG_GAP_METHODS = ("pca", "error")
MIN_COMPLETE = 10          # frames with the marker and all its donors, for a PCA model
PCA_VARIANCE = 0.999       # fraction of the variance kept by the PCA model


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a 1-D boolean array as (start, stop) pairs, stop exclusive."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def missing_mask(rec: Recording) -> np.ndarray:
    """(frames, markers) bool, True where any coordinate of a sample is NaN or infinite."""
    return ~np.isfinite(rec.points).all(axis=2)


def gap_report(rec: Recording, filled_by_us: np.ndarray | None = None,
               methods: list[str] | None = None) -> pd.DataFrame:
    """One row per marker: missing samples, gaps, filled samples and the fill method.

    missing_* and gaps describe ``rec`` as given; filled_frames counts the samples flagged in
    ``rec.filled`` (by the producer) or in ``filled_by_us``.
    """
    miss = missing_mask(rec)
    filled = rec.filled.copy()
    if filled_by_us is not None:
        filled |= filled_by_us
    rows = []
    for j, label in enumerate(rec.labels):
        r = runs(miss[:, j])
        rows.append({
            "marker": str(label),
            "frames": rec.n_frames,
            "missing_frames": int(miss[:, j].sum()),
            "missing_fraction": float(miss[:, j].mean()) if rec.n_frames else 0.0,
            "longest_gap_frames": max((b - a for a, b in r), default=0),
            "n_gaps": len(r),
            "filled_frames": int(filled[:, j].sum()),
            "fill_method": methods[j] if methods is not None else "none",
        })
    return pd.DataFrame(rows, columns=REPORT_COLUMNS)


def _n_components(s: np.ndarray) -> int:
    """Principal components needed for PCA_VARIANCE of the variance (singular values s)."""
    var = s ** 2
    k = int(np.searchsorted(np.cumsum(var) / max(var.sum(), 1e-300), PCA_VARIANCE) + 1)
    return max(1, min(k, len(s)))


def _pca_fill(pts: np.ndarray, long_mask: np.ndarray, src: str, rate: float,
              labels: list[str]) -> np.ndarray:
    """Fill the long gaps (long_mask) of pts (frames, n, 3) from the other markers' motion.

    For a gap of marker j: donors are the markers measured throughout the gap; the model is
    the PCA of [donors, j] over the frames where all of them are measured (mean mu,
    directions V, k components); in the gap, z = argmin |V_d z - (x_d - mu_d)| and
    x_j = mu_j + V_j z (Gloersen & Federolf 2016, reconstruction from marker
    intercorrelations).
    """
    F, n, _ = pts.shape
    miss = ~np.isfinite(pts).all(axis=2)
    out = pts.copy()
    models: dict[tuple, tuple] = {}
    for j in np.flatnonzero(long_mask.any(axis=0)):
        for a, b in runs(long_mask[:, j]):
            donors = tuple(int(k) for k in np.flatnonzero(~miss[a:b].any(axis=0)) if k != j)
            key = (int(j), donors)
            if key not in models:
                cols = list(donors) + [int(j)]
                train = np.flatnonzero(~miss[:, cols].any(axis=1))
                if not donors or train.size < MIN_COMPLETE:
                    raise InputError(
                        f"{src}: marker {labels[j]!r}: cannot reconstruct the gap starting at "
                        f"t = {a / rate:.3f} s: {len(donors)} other marker(s) measured "
                        f"throughout it and {train.size} frame(s) with all of them and "
                        f"{labels[j]!r} (need >= 1 and >= {MIN_COMPLETE})")
                T = pts[train][:, cols, :].reshape(train.size, -1)
                mu = T.mean(axis=0)
                _, sv, Vt = np.linalg.svd(T - mu, full_matrices=False)
                k = min(_n_components(sv), 3 * len(donors))  # no more scores than observations
                models[key] = (mu, Vt[:k].T)
            mu, V = models[key]
            nd = 3 * len(donors)
            xd = pts[a:b][:, list(donors), :].reshape(b - a, nd)
            z, *_ = np.linalg.lstsq(V[:nd], (xd - mu[:nd]).T, rcond=None)
            out[a:b, j, :] = (mu[nd:, None] + V[nd:] @ z).T
    return out


def fill_gaps(rec: Recording, max_interp_s: float = 0.1, long_gaps: str = "pca"
              ) -> tuple[Recording, pd.DataFrame]:
    """Fill all gaps of ``rec``; returns the filled recording and the gap report.

    Gaps of at most ``max_interp_s`` seconds (``round(max_interp_s * rate)`` frames) with
    measured samples on both sides: cubic spline. Others: ``long_gaps`` = "pca" (reconstruction
    from the other markers) or "error" (InputError naming the marker and the gap's start
    time). A marker missing in every frame is an InputError. Every sample filled here is set
    True in ``filled.filled``; samples flagged by the producer stay flagged.
    """
    src = rec.source or "recording"
    if long_gaps not in LONG_GAP_METHODS:
        raise InputError(f"{src}: long_gaps setting must be one of {', '.join(LONG_GAP_METHODS)}"
                         f", got {long_gaps!r}")
    if not np.isfinite(max_interp_s) or max_interp_s < 0:
        raise InputError(f"{src}: max_interp_s setting must be >= 0 s, got {max_interp_s!r}")
    max_frames = int(round(max_interp_s * rec.rate))
    miss = missing_mask(rec)
    never = [rec.labels[j] for j in np.flatnonzero(miss.all(axis=0))]
    if never and rec.n_frames:
        raise InputError(f"{src}: marker(s) {', '.join(never)} missing in every frame; exclude "
                         "them in the settings or fix the recording")
    pts = rec.points.copy()
    pts[miss] = np.nan  # a partly missing sample counts as missing in all three coordinates
    F = rec.n_frames
    frames = np.arange(F, dtype=float)
    used_cubic = np.zeros(rec.n_markers, dtype=bool)
    long_mask = np.zeros_like(miss)
    for j in np.flatnonzero(miss.any(axis=0)):
        valid = np.flatnonzero(~miss[:, j])
        spline = CubicSpline(valid, pts[valid, j, :], axis=0) if valid.size >= 4 else None
        for a, b in runs(miss[:, j]):
            interior = a > 0 and b < F
            if spline is not None and interior and b - a <= max_frames:
                pts[a:b, j, :] = spline(frames[a:b])
                used_cubic[j] = True
            else:
                long_mask[a:b, j] = True
    if long_mask.any():
        if long_gaps == "error":
            j = int(np.flatnonzero(long_mask.any(axis=0))[0])
            a, b = runs(long_mask[:, j])[0]
            why = ("at the start of the take" if a == 0 else "at the end of the take"
                   if b == F else f"longer than {max_interp_s} s")
            raise InputError(f"{src}: marker {rec.labels[j]!r} has a gap of {b - a} frame(s) "
                             f"starting at t = {a / rec.rate:.3f} s ({why}) and long_gaps is "
                             "'error'")
        pts = _pca_fill(pts, long_mask, src, rec.rate, rec.labels)
    used_pca = long_mask.any(axis=0)
    methods = ["+".join(m for m, u in (("cubic", c), ("pca", p)) if u) or "none"
               for c, p in zip(used_cubic, used_pca, strict=True)]
    filled = Recording(list(rec.labels), pts, rec.rate, rec.source, rec.filled | miss)
    return filled, gap_report(rec, filled_by_us=miss, methods=methods)
