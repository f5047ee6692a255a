"""Gap report and gap filling of marker trajectories.

A sample is missing when any of its coordinates is NaN; gaps are runs of missing samples.

* Short interior gaps (at most ``max_interp_s`` seconds, with measured samples on both sides)
  are filled by a cubic spline (scipy ``CubicSpline``, not-a-knot) through all the marker's
  measured samples, evaluated in the gap.
* Longer gaps, and gaps at the start or end of a take (which cannot be interpolated), go to the
  long-gap method. ``"pca"`` reconstructs them from the other markers' correlated motion, in
  the manner of Gloersen & Federolf (2016, J. Biomech. 49:1180), one gap at a time, from a
  window of the take around the gap (``WINDOW_GAPS`` gap lengths, at least ``WINDOW_MIN_S``
  seconds, either side): the candidates are the markers measured throughout the gap; the
  donors are the ``n_donors`` (default 30) candidates that best predict the gap's marker by
  a linear fit on their coordinates over the window; the frames x 3(d + 1) matrix of the
  donors and the gap's marker over the window's frames where all of them are measured is
  centred (mean mu) and the eigenvectors of its covariance give the PCA directions V (k
  components for 99.9 % of the variance, at most 3d); in the gap the donors' coordinates fit
  the scores, z = argmin |V_d z - (x_d - mu_d)|, and the marker is x_j = mu_j + V_j z.
  Filled values of other markers are never used as donors, so the result does not depend on
  the order of the gaps, and no frame needs every marker. A gap's cost grows with its window
  and the number of markers, not with the length of the take.
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
* pca on real markers (AnimFace, both takes, 5 markers, 1 s gaps at 3 places, 30 gaps): RMS
  error mean 0.84 mm, max 2.7 mm with 30 donors and a 10 s window; 10 donors: 2.2 / 14 mm,
  15: 1.3 / 6.3, 20: 1.1 / 3.9, every marker (40) over the whole take (the earlier method):
  1.03 / 3.8 mm.
* pca on a dense face (the canonical mesh's 468 vertices moved by 12 smooth fields plus
  0.05 mm noise, 30 Hz), gaps of 1-5 s, one at the start of the take: RMS error < 0.1 mm
  (about the noise), max < 0.4 mm.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from facemotion.errors import InputError
from facemotion.io.recording import Recording, finite_samples

if TYPE_CHECKING:  # pandas and scipy are imported where they are used (lazy imports)
    import pandas as pd

REPORT_COLUMNS = ["marker", "frames", "missing_frames", "missing_fraction",
                  "longest_gap_frames", "n_gaps", "filled_frames", "fill_method"]
LONG_GAP_METHODS = ("pca", "error")
MIN_COMPLETE = 10          # frames with the marker and all its donors, for a PCA model
PCA_VARIANCE = 0.999       # fraction of the variance kept by the PCA model
N_DONORS = 30              # donor markers per gap: the best predictors of the gap's marker
WINDOW_GAPS = 10           # a gap's model learns from this many gap lengths either side ...
WINDOW_MIN_S = 10.0        # ... and at least this many seconds either side
SCORE_FRAMES = 1000        # frames (evenly spaced in the window) that rank the donors


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a 1-D boolean array as (start, stop) pairs, stop exclusive."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def missing_mask(rec: Recording) -> np.ndarray:
    """(frames, markers) bool, True where any coordinate of a sample is NaN or infinite."""
    return _missing(rec.points)


def _missing(points: np.ndarray) -> np.ndarray:
    return ~finite_samples(points)


def gap_report(rec: Recording, filled_by_us: np.ndarray | None = None,
               methods: list[str] | None = None, missing: np.ndarray | None = None
               ) -> pd.DataFrame:
    """One row per marker: missing samples, gaps, filled samples and the fill method.

    missing_* and gaps describe ``rec`` as given; filled_frames counts the samples flagged in
    ``rec.filled`` (by the producer) or in ``filled_by_us``. ``missing``: the missing mask of
    ``rec`` if already computed.
    """
    import pandas as pd

    miss = missing_mask(rec) if missing is None else missing
    filled = rec.filled.copy()
    if filled_by_us is not None:
        filled |= filled_by_us
    n, F = rec.n_markers, rec.n_frames
    if n == 0:
        return pd.DataFrame([], columns=REPORT_COLUMNS)
    longest = np.zeros(n, dtype=np.int64)
    n_gaps = np.zeros(n, dtype=np.int64)
    missing_frames = miss.sum(axis=0, dtype=np.int64)
    for j in np.flatnonzero(missing_frames):
        r = runs(miss[:, j])
        longest[j] = max(b - a for a, b in r)
        n_gaps[j] = len(r)
    return pd.DataFrame({
        "marker": [str(label) for label in rec.labels],
        "frames": np.full(n, F, dtype=np.int64),
        "missing_frames": missing_frames,
        # a count over F: the same value as the mean of the column (exact sums of 0 and 1)
        "missing_fraction": missing_frames / F if F else np.zeros(n),
        "longest_gap_frames": longest,
        "n_gaps": n_gaps,
        "filled_frames": filled.sum(axis=0, dtype=np.int64),
        "fill_method": list(methods) if methods is not None else ["none"] * n,
    }, columns=REPORT_COLUMNS)


def _n_components(eigenvalues: np.ndarray) -> int:
    """Principal components needed for PCA_VARIANCE of the variance (eigenvalues, descending)."""
    var = np.maximum(eigenvalues, 0.0)
    k = int(np.searchsorted(np.cumsum(var) / max(var.sum(), 1e-300), PCA_VARIANCE) + 1)
    return max(1, min(k, len(var)))


def _window(a: int, b: int, F: int, rate: float) -> tuple[int, int]:
    """Frames [lo, hi) a gap [a, b) learns from: WINDOW_GAPS gap lengths (at least
    WINDOW_MIN_S seconds) either side, clipped to the take."""
    w = max(WINDOW_GAPS * (b - a), int(round(WINDOW_MIN_S * rate)))
    return max(0, a - w), min(F, b + w)


def _donor_scores(xj: np.ndarray, mj: np.ndarray, xc: np.ndarray, mc: np.ndarray
                  ) -> np.ndarray:
    """How well each candidate predicts marker j: the fraction of j's variance explained by
    a linear fit on the candidate's three coordinates, tr(C_jk C_kk^-1 C_kj) / tr(C_jj),
    over the frames where both are measured.

    xj (L, 3), mj (L,) bool; xc (L, c, 3), mc (L, c) bool (NaN samples are masked out).
    """
    L, c, _ = xc.shape
    w = (mj[:, None] & mc).astype(float)  # (L, c) frames where j and candidate are measured
    xj0 = np.where(mj[:, None], xj, 0.0)
    xc0 = np.where(mc[..., None], xc, 0.0)
    Y = w[..., None] * xc0                                     # (L, c, 3)
    cnt = np.maximum(w.sum(axis=0), 1.0)[:, None]
    mean_j = (w.T @ xj0) / cnt                                 # (c, 3)
    mean_k = Y.sum(axis=0) / cnt                               # (c, 3)
    Sjj = (w.T @ (xj0[:, :, None] * xj0[:, None, :]).reshape(L, 9)).reshape(c, 3, 3)
    Sjk = (xj0.T @ Y.reshape(L, 3 * c)).reshape(3, c, 3).transpose(1, 0, 2)  # (c, 3, 3)
    Skk = np.empty((c, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            Skk[:, a, b] = Skk[:, b, a] = np.einsum("lc,lc->c", Y[..., a], xc0[..., b])
    Cjj = Sjj / cnt[..., None] - mean_j[:, :, None] * mean_j[:, None, :]
    Ckk = Skk / cnt[..., None] - mean_k[:, :, None] * mean_k[:, None, :]
    Cjk = Sjk / cnt[..., None] - mean_j[:, :, None] * mean_k[:, None, :]
    tr_kk = np.trace(Ckk, axis1=1, axis2=2)
    ridge = 1e-9 * np.maximum(tr_kk, 1e-300)[:, None, None] * np.eye(3)
    # C_jk C_kk^-1 C_kj, batched (a tiny ridge keeps a static candidate finite)
    sol = np.linalg.solve(Ckk + ridge, Cjk.transpose(0, 2, 1))  # (c, 3, 3) = C_kk^-1 C_kj
    explained = np.einsum("cab,cba->c", Cjk, sol)
    score = explained / np.maximum(np.trace(Cjj, axis1=1, axis2=2), 1e-300)
    score[w.sum(axis=0) < MIN_COMPLETE] = -np.inf  # too few shared frames to judge
    return score


def _pca_fill(pts: np.ndarray, long_mask: np.ndarray, src: str, rate: float,
              labels: list[str], n_donors: int = N_DONORS,
              targets: np.ndarray | None = None) -> np.ndarray:
    """Fill the long gaps (long_mask) of pts (frames, n, 3) in place from correlated markers.

    Every sample of pts outside long_mask must be finite (measured or filled by cubic).

    For a gap [a, b) of marker j: the window is WINDOW_GAPS gap lengths (at least
    WINDOW_MIN_S seconds) either side; the candidates are the markers measured throughout the gap,
    the donors the ``n_donors`` candidates that best predict j over the window
    (:func:`_donor_scores`). The model is the PCA of [donors, j] over the window's frames where
    all of them are measured: mean mu, eigenvectors V of the covariance (T - mu)^T (T - mu)
    (k components for PCA_VARIANCE of the variance, at most 3d); in the gap
    z = argmin |V_d z - (x_d - mu_d)| and x_j = mu_j + V_j z (Gloersen & Federolf 2016,
    reconstruction from marker intercorrelations). Filled values are never donors. ``targets``
    (same shape as long_mask): only the gaps starting on a True sample are filled, the others
    stay missing (a window of a take filled piece by piece). The cost of
    a gap grows with its window (about 2 WINDOW_GAPS + 1 gap lengths) times the markers, not
    with the length of the take.
    """
    F, n, _ = pts.shape
    miss = long_mask
    fills = []
    for j in np.flatnonzero(long_mask.any(axis=0)):
        for a, b in runs(long_mask[:, j]):
            if targets is not None and not targets[a, j]:
                continue
            lo, hi = _window(a, b, F, rate)
            cand = np.flatnonzero(~miss[a:b].any(axis=0))
            cand = cand[cand != j]
            if cand.size > n_donors:
                # scores from at most SCORE_FRAMES frames of the window, evenly spaced
                f = np.arange(lo, hi, max(1, (hi - lo) // SCORE_FRAMES))
                score = _donor_scores(pts[f, j], ~miss[f, j], pts[f[:, None], cand],
                                      ~miss[f[:, None], cand])
                cand = np.sort(cand[np.argsort(-score, kind="stable")[:n_donors]])
            donors = [int(k) for k in cand]
            cols = donors + [int(j)]
            train = lo + np.flatnonzero(~miss[lo:hi, cols].any(axis=1))
            if donors and train.size < MIN_COMPLETE:  # the window is too sparse: whole take
                train = np.flatnonzero(~miss[:, cols].any(axis=1))
            if not donors or train.size < MIN_COMPLETE:
                raise InputError(
                    f"{src}: marker {labels[j]!r}: cannot reconstruct the gap starting at "
                    f"t = {a / rate:.3f} s: {len(donors)} other marker(s) measured "
                    f"throughout it and {train.size} frame(s) with all of them and "
                    f"{labels[j]!r} (need >= 1 and >= {MIN_COMPLETE})")
            T = pts[train[:, None], cols].reshape(train.size, -1)
            mu = T.mean(axis=0)
            Tc = T - mu
            # eigenvectors of the covariance, largest first (the PCA directions)
            lam, V = np.linalg.eigh(Tc.T @ Tc)
            lam, V = lam[::-1], V[:, ::-1]
            k = min(_n_components(lam), 3 * len(donors))  # no more scores than observations
            V = V[:, :k]
            nd = 3 * len(donors)
            xd = pts[a:b, donors].reshape(b - a, nd)
            z, *_ = np.linalg.lstsq(V[:nd], (xd - mu[:nd]).T, rcond=None)
            fills.append((a, b, int(j), (mu[nd:, None] + V[nd:] @ z).T))
    for a, b, j, x in fills:  # after all models: filled values are never donors
        pts[a:b, j, :] = x
    return pts


def fill_gaps(rec: Recording, max_interp_s: float = 0.1, long_gaps: str = "pca",
              n_donors: int = N_DONORS) -> tuple[Recording, pd.DataFrame]:
    """Fill all gaps of ``rec``; returns the filled recording and the gap report.

    Gaps of at most ``max_interp_s`` seconds (``round(max_interp_s * rate)`` frames) with
    measured samples on both sides: cubic spline. Others: ``long_gaps`` = "pca" (reconstruction
    from the ``n_donors`` best-correlated other markers) or "error" (InputError naming the
    marker and the gap's start time). A marker missing in every frame is an InputError.
    Every sample filled here is set True in ``filled.filled``; samples flagged by the
    producer stay flagged.
    """
    from scipy.interpolate import CubicSpline  # imported here: a heavy import few jobs need

    src = rec.source or "recording"
    if long_gaps not in LONG_GAP_METHODS:
        raise InputError(f"long_gaps: must be one of {', '.join(LONG_GAP_METHODS)}"
                         f", got {long_gaps!r}")
    if isinstance(n_donors, bool) or not isinstance(n_donors, int | np.integer) or n_donors < 1:
        raise InputError(f"n_donors: must be an integer >= 1, got {n_donors!r}")
    if not np.isfinite(max_interp_s) or max_interp_s < 0:
        raise InputError(f"max_interp_s: must be >= 0 s, got {max_interp_s!r}")
    max_frames = int(round(max_interp_s * rec.rate))
    miss = missing_mask(rec)
    never = [rec.labels[j] for j in np.flatnonzero(miss.all(axis=0))]
    if never and rec.n_frames:
        raise InputError(f"{src}: marker(s) {', '.join(never)} missing in every frame; exclude "
                         "them (exclude_markers) or fix the recording")
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
        pts = _pca_fill(pts, long_mask, src, rec.rate, rec.labels, int(n_donors))
    used_pca = long_mask.any(axis=0)
    methods = ["+".join(m for m, u in (("cubic", c), ("pca", p)) if u) or "none"
               for c, p in zip(used_cubic, used_pca, strict=True)]
    filled = Recording(list(rec.labels), pts, rec.rate, rec.source, rec.filled | miss)
    return filled, gap_report(rec, filled_by_us=miss, methods=methods, missing=miss)
