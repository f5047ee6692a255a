"""The held-out error curve (:func:`facemotion.regions.prediction.error_curve`) from held-out
rows read in blocks, never the whole held-out matrix.

Each held-out frame's residuals depend on that frame alone (E^(k) = B_P - C[:, :k] R[:k, :] row
by row, C = B_P R^-1), so a block of frames gives its frames' residual distances for every k.
The measures then come from sums over blocks:

* means, RMS, the per-marker relative error, the pooled relative error, the maximum: running
  sums, counts and maxima, exact (the sums added in another order than the whole-matrix
  curve's: they agree to round-off);
* the median: exact on the blocks' residuals (which agree with the whole matrix's to
  round-off: BLAS groups its sums by the rows it is given), by selection over three passes
  over the blocks (residuals recomputed, the same numbers each time): pass 1 gives each k's
  count, minimum and maximum; pass 2 counts the distances in ``MEDIAN_BINS`` equal bins
  between them and finds the bin(s) holding the middle order statistic(s); pass 3 keeps only
  the distances in those bins and selects the middle one(s) among them. Memory: one block's
  residuals and, per k, the bin counts and one bin's values.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
import pandas as pd
import scipy.linalg

from facemotion.ranking.result import MarkerRanking
from facemotion.regions.prediction import CURVE_COLUMNS, _align, _k_stop, _sq_dist, _zero_row

#: Bins of the median's second pass.
MEDIAN_BINS = 4096


def _block_distances(rk: MarkerRanking, B: np.ndarray, labels, rank: int):
    """For one block of held-out rows: (mag (n,), then for k = 1..rank the (n - k, frames)
    3-D residual distances of the secondary markers) - the whole-matrix curve's arithmetic."""
    Bp = _align(rk, B, labels)
    F = Bp.shape[0] // 3
    n = rk.n
    R = rk.R
    C = scipy.linalg.solve_triangular(R[:rank, :rank], Bp[:, :rank].T, trans="T").T
    E = np.ascontiguousarray(Bp.reshape(F, 3, n).transpose(2, 1, 0))
    Cm = np.ascontiguousarray(C.reshape(F, 3, rank).transpose(2, 1, 0))
    yield np.sqrt(_sq_dist(E)).sum(axis=1)
    step = np.empty_like(E)
    for k in range(1, rank + 1):
        Es = E[k:]
        np.subtract(Es, np.multiply(R[k - 1, k:, None, None], Cm[k - 1], out=step[k:]),
                    out=Es)
        yield _sq_dist(Es)


def _passes(rk, blocks, labels, rank, visit) -> None:
    """One pass over the blocks: visit(k, squared distances (n - k, f)) and visit(0, mag)."""
    for B in blocks():
        it = _block_distances(rk, B, labels, rank)
        visit(0, next(it))
        for k, D2 in enumerate(it, start=1):
            visit(k, D2)


def _middle_ranks(count: int) -> list[int]:
    h = count // 2
    return [h] if count % 2 else [h - 1, h]


def streamed_error_curve(train_ranking: MarkerRanking,
                         blocks: Callable[[], Iterable[np.ndarray]], labels: Sequence[str],
                         k_max: int | None = None) -> pd.DataFrame:
    """:func:`~facemotion.regions.prediction.error_curve` of the held-out rows that
    ``blocks()`` yields (each call a fresh pass; blocks of whole frames, columns ``labels``)."""
    rk = train_ranking
    n, rank = rk.n, _k_stop(rk, k_max)
    sq = np.zeros(rank + 1)
    cnt = np.zeros(rank + 1, dtype=np.int64)
    lo, hi = np.full(rank + 1, np.inf), np.full(rank + 1, -np.inf)
    per_marker = [np.zeros(n - k) for k in range(rank + 1)]
    mag = np.zeros(n)

    def first(k, D2):
        if k == 0:
            mag[:] += D2
            return
        dist = np.sqrt(D2)
        sq[k] += D2.sum()
        cnt[k] += dist.size
        per_marker[k] += dist.sum(axis=1)
        lo[k], hi[k] = min(lo[k], dist.min()), max(hi[k], dist.max())

    _passes(rk, blocks, labels, rank, first)
    medians = _medians(rk, blocks, labels, rank, cnt, lo, hi)
    lab = rk.labels_in_order
    out = []
    for k in range(1, rank + 1):
        total = float(per_marker[k].sum())
        m = mag[k:]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = float((per_marker[k] / m).mean())
        out.append({
            "k": k, "mean_abs_error_mm": total / cnt[k],
            "rms_error_mm": float(np.sqrt(sq[k] / cnt[k] / 3.0)),
            "median_abs_error_mm": medians[k], "max_abs_error_mm": float(hi[k]),
            "rel_error_per_marker": rel,
            "rel_error_pooled": total / float(m.sum()) if m.sum() > 0 else float("nan"),
            "pivot_marker": lab[k - 1], "main_markers": ",".join(lab[:k]),
        })
    out.append(_zero_row(n, lab))
    return pd.DataFrame(out, columns=CURVE_COLUMNS)


def _medians(rk, blocks, labels, rank, cnt, lo, hi) -> dict[int, float]:
    """Each k's exact median distance by the two selection passes (module notes)."""
    counts = np.zeros((rank + 1, MEDIAN_BINS), dtype=np.int64)
    width = np.where(hi > lo, (hi - lo) / MEDIAN_BINS, 1.0)

    def bins(k, dist):
        return np.minimum(((dist - lo[k]) / width[k]).astype(np.int64), MEDIAN_BINS - 1)

    def second(k, D2):
        if k:
            counts[k] += np.bincount(bins(k, np.sqrt(D2)).ravel(), minlength=MEDIAN_BINS)

    _passes(rk, blocks, labels, rank, second)
    want = {}   # k -> [(bin, rank within the bin)]
    for k in range(1, rank + 1):
        c = np.cumsum(counts[k])
        want[k] = [(int(b), r - (int(c[b - 1]) if b else 0))
                   for r in _middle_ranks(int(cnt[k]))
                   for b in [int(np.searchsorted(c, r, side="right"))]]
    kept = {k: [] for k in want}

    def third(k, D2):
        if k:
            dist = np.sqrt(D2).ravel()
            sel = np.isin(bins(k, dist), [b for b, _ in want[k]])
            kept[k].append(dist[sel])

    _passes(rk, blocks, labels, rank, third)
    out = {}
    for k, targets in want.items():
        vals = np.concatenate(kept[k])
        picks = []
        for b, r in targets:
            in_bin = np.sort(vals[bins(k, vals) == b])
            picks.append(float(in_bin[r]))
        out[k] = picks[0] if len(picks) == 1 else (picks[0] + picks[1]) / 2.0
    return out
