"""Gap filling of a take in windows of frames, equal to :func:`facemotion.ingest.gaps.fill_gaps`
of the whole take.

A block of frames [a, b) is filled from a window [lo, hi) of the take around it, large enough
that every fill that reaches the block sees what the whole-take fill sees:

* a short gap (cubic spline through the marker's measured samples) needs ``SPLINE_KNOTS``
  measured samples of its marker either side (or the take's end). The not-a-knot spline's
  dependence on a sample k knots away decays like (2 - sqrt 3)^k = 0.268^k, so 64 knots leave
  a difference below 1e-36 of the motion, far under round-off: the fills agree with the
  whole-take fill to round-off (``FILL_RTOL``, the tolerance the tests hold them to);
* a long gap (PCA from donor markers) needs its model window
  (:func:`facemotion.ingest.gaps._window`, the same frames), and within it every other gap's
  extent and every short gap's spline extent, so that the donors' data (measured and cubic
  values) and which samples count as missing are those of the whole take. The model is then
  computed from the same numbers.

Gaps are classified (short / long) on the whole take, once (:func:`plan_gaps`). One case
differs: when a gap's model window has fewer than ``MIN_COMPLETE`` complete frames, the
whole-take fill falls back to the whole take; the window fill to its window.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facemotion.errors import InputError
from facemotion.ingest.gaps import N_DONORS, _pca_fill, _window, runs

#: Measured samples either side of a short gap in its window (see the module notes).
SPLINE_KNOTS = 64
#: Relative agreement of the window fill with the whole-take fill (tests).
FILL_RTOL = 1e-9


@dataclass
class GapPlan:
    """Every gap of a take: marker, [a, b), long or not, the frames [lo, hi) its fill needs."""

    F: int
    j: np.ndarray
    a: np.ndarray
    b: np.ndarray
    long: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    cubic: np.ndarray          # (markers,) some gap filled by cubic
    pca: np.ndarray            # (markers,) some gap filled by PCA

    def window(self, a: int, b: int) -> tuple[int, int]:
        """The frames [lo, hi) from which the block [a, b) is filled."""
        hit = (self.b > a) & (self.a < b)
        if not hit.any():
            return a, b
        return min(a, int(self.lo[hit].min())), max(b, int(self.hi[hit].max()))


def _spline_extent(valid: np.ndarray, a: int, b: int, F: int) -> tuple[int, int]:
    p = int(np.searchsorted(valid, a))
    q = int(np.searchsorted(valid, b))
    lo = int(valid[p - SPLINE_KNOTS]) if p >= SPLINE_KNOTS else 0
    hi = int(valid[q + SPLINE_KNOTS - 1]) + 1 if q + SPLINE_KNOTS - 1 < valid.size else F
    return lo, hi


def plan_gaps(missing: np.ndarray, rate: float, max_interp_s: float, long_gaps: str,
              labels: list[str], src: str) -> GapPlan:
    """The gaps of a take's (frames, markers) missing mask, classified as ``fill_gaps`` does,
    with the window each needs; its errors (a marker never measured, a long gap with
    long_gaps 'error') with ``fill_gaps``'s words."""
    F, n = missing.shape
    never = [labels[j] for j in np.flatnonzero(missing.all(axis=0))]
    if never and F:
        raise InputError(f"{src}: marker(s) {', '.join(never)} missing in every frame; exclude "
                         "them (exclude_markers) or fix the recording")
    max_frames = int(round(max_interp_s * rate))
    rows = []
    for j in np.flatnonzero(missing.any(axis=0)):
        valid = np.flatnonzero(~missing[:, j])
        for a, b in runs(missing[:, j]):
            short = valid.size >= 4 and a > 0 and b < F and b - a <= max_frames
            lo, hi = _spline_extent(valid, a, b, F) if short else _window(a, b, F, rate)
            rows.append((j, a, b, not short, lo, hi))
    g = np.array(rows, dtype=np.int64).reshape(-1, 6)
    plan = GapPlan(F, g[:, 0], g[:, 1], g[:, 2], g[:, 3].astype(bool), g[:, 4].copy(),
                   g[:, 5].copy(), np.zeros(n, bool), np.zeros(n, bool))
    plan.cubic[plan.j[~plan.long]] = True
    plan.pca[plan.j[plan.long]] = True
    if plan.long.any() and long_gaps == "error":
        first = np.lexsort((plan.a[plan.long], plan.j[plan.long]))[0]
        j, a, b = (int(x[plan.long][first]) for x in (plan.j, plan.a, plan.b))
        why = ("at the start of the take" if a == 0 else "at the end of the take"
               if b == F else f"longer than {max_interp_s} s")
        raise InputError(f"{src}: marker {labels[j]!r} has a gap of {b - a} frame(s) "
                         f"starting at t = {a / rate:.3f} s ({why}) and long_gaps is 'error'")
    # a long gap's model reads its window: every gap there must be as in the whole take
    ext_lo = np.where(plan.long, plan.a, plan.lo)
    ext_hi = np.where(plan.long, plan.b, plan.hi)
    for i in np.flatnonzero(plan.long):
        wlo, whi = plan.lo[i], plan.hi[i]
        inside = (plan.b > wlo) & (plan.a < whi)
        plan.lo[i] = min(wlo, int(ext_lo[inside].min()))
        plan.hi[i] = max(whi, int(ext_hi[inside].max()))
    return plan


def fill_window(pts: np.ndarray, lo: int, a: int, b: int, plan: GapPlan, rate: float,
                labels: list[str], src: str) -> np.ndarray:
    """Frames [a, b) of the take filled, from ``pts``: its frames [lo, lo + len(pts)) (NaN
    where missing). The values equal those of the whole-take fill (module notes)."""
    hi = lo + len(pts)
    if not ((plan.b > lo) & (plan.a < hi)).any():
        return pts[a - lo:b - lo]  # no gap in the window: nothing to fill
    from scipy.interpolate import CubicSpline  # a heavy import, for takes with gaps
    miss = ~np.isfinite(pts).all(axis=2)
    pts = pts.copy()
    pts[miss] = np.nan
    inside = (plan.a >= lo) & (plan.b <= hi)
    cubic = inside & ~plan.long & (plan.lo >= lo) & (plan.hi <= hi)
    for j in np.unique(plan.j[cubic]):
        valid = np.flatnonzero(~miss[:, j])
        # the take's frame numbers as abscissae, as the whole-take fill has them
        spline = CubicSpline(valid + lo, pts[valid, j, :], axis=0)
        for i in np.flatnonzero(cubic & (plan.j == j)):
            ga, gb = plan.a[i] - lo, plan.b[i] - lo
            pts[ga:gb, j, :] = spline(np.arange(plan.a[i], plan.b[i], dtype=float))
            miss[ga:gb, j] = False
    targets = inside & plan.long & (plan.b > a) & (plan.a < b)
    if targets.any():
        mark = np.zeros_like(miss)
        mark[plan.a[targets] - lo, plan.j[targets]] = True
        pts = _pca_fill(pts, miss, src, rate, labels, N_DONORS, targets=mark)
    return pts[a - lo:b - lo]
