"""The held-out error curve (:func:`facemotion.regions.prediction.error_curve`) from held-out
rows read in blocks, never the whole held-out matrix.

Each held-out frame's residuals depend on that frame alone (E^(k) = B_P - C[:, :k] R[:k, :] row
by row, C = B_P R^-1), so a block of frames gives its frames' residual distances for every k.
Within a block the frames go through all k in tiles of ``TILE_FRAMES`` frames: a tile's
residuals stay in the processor's cache from one k to the next, where the rank-one updates of
a whole block would stream it from memory at every k. The arithmetic of each value is the
whole-matrix curve's (the same rank-one updates, the same squared distances D2). With
``threads`` > 1 the tiles of each block are shared out among threads (numpy releases the GIL
in its loops), each adding into sums of its own, added in thread order at the end.

* means, RMS, the per-marker relative error, the pooled relative error: running sums and
  counts, exact (the sums added in another order than the whole-matrix curve's: they agree to
  round-off);
* the maximum and the median: selected among the squared distances D2, then the square root
  taken (it is monotone and correctly rounded: the same numbers as selecting among the
  distances). The maximum is a running maximum. The median is exact, by selection: a pilot
  pass computes the residuals of every ``PILOT_EVERY``-th frame only and keeps a sample of
  each k's D2 (at most ``SAMPLE_BYTES``); the sample's quantiles around the middle, widened by
  ``SAMPLE_Z`` standard errors (and narrowed so that the values in it, expected, fill at most
  a quarter of ``KEEP_BYTES``), give an interval of D2 values; the main pass (all frames, the
  sums above) counts the values below the interval and keeps those in it. When the middle
  order statistic(s) fall among the kept values (the usual case: a pilot and one full pass),
  they are selected there. Otherwise (the sample misled, or the interval holds more than
  ``KEEP_BYTES``) the interval known to hold them is cut into ``MEDIAN_BINS`` equal ranges of
  the values' bit patterns (monotone in the value for D2 >= 0) and a further pass counts each;
  the range holding the order statistic becomes the interval, until its values fit in
  ``KEEP_BYTES`` (then a pass keeps them) or it is one value. Memory: one block and each
  thread's tiles, the sample and the kept values (``KEEP_BYTES`` per thread at most).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd
import scipy.linalg
from threadpoolctl import threadpool_limits

from facemotion.errors import InputError
from facemotion.ranking.result import MarkerRanking
from facemotion.regions.prediction import CURVE_COLUMNS, _k_stop, _pivot_columns, _zero_row

#: Bytes of a tile's residuals (markers x 3 x frames): they stay in cache across the k.
TILE_BYTES = 2 * 2**20
#: Frames of a tile (None: as many as fit in TILE_BYTES, 8 to 128).
TILE_FRAMES: int | None = None
#: The pilot pass computes the residuals of every PILOT_EVERY-th frame, for the median's sample.
PILOT_EVERY = 8
#: Bound on the bytes of the median's sample (all k together).
SAMPLE_BYTES = 64 * 2**20
#: Standard errors of the sample quantile by which the median's first interval is widened.
SAMPLE_Z = 15.0
#: Bound on the bytes of D2 values kept for the median's selection (all k together).
KEEP_BYTES = 256 * 2**20
#: Ranges a pass cuts the median's interval into.
MEDIAN_BINS = 4096
#: Passes after the main one before the selection gives up (a range of 2^63 bit patterns is
#: one value after 6 cuts into 4096).
MAX_PASSES = 16
_TOP = int(np.array(np.inf).view(np.int64))  # bit pattern of +inf: above every finite D2


def _tile_frames(n: int) -> int:
    """Frames of a tile of n markers: TILE_FRAMES, or as many as fit in TILE_BYTES."""
    return TILE_FRAMES or max(8, min(128, TILE_BYTES // (24 * n)))


class _Tiles:
    """One thread's buffers for its tiles (the residuals E, C, the update's product and D2)
    and the tiles' arithmetic: marker-major, E[j] = marker j's (3, frames), when a tile has
    at least 64 frames; else one (frames x markers) matrix per axis, E[c], so that every
    update and sum still runs along a long row. The same operations on the same numbers."""

    def __init__(self, n: int, rank: int):
        self.m = _tile_frames(n)
        self.marker_major = self.m >= 64
        self.E = np.empty(n * 3 * self.m)
        self.C = np.empty(rank * 3 * self.m)
        self.step = np.empty_like(self.E)
        self.D2 = np.empty(n * self.m)

    def run(self, rk, B, cols, C, starts, visitor, mag: bool) -> None:
        """The tiles of B (pivot order ``cols``, C = B_P[:, :rank] R11^-1) that start at the
        frames ``starts``: ``visitor.visit(k, D2)`` for k = 1..rank, D2 (frames, n - k) the
        tile's squared 3-D residual distances of the secondary markers (a view of a buffer,
        perhaps transposed: used before the next call); with ``mag``, ``visitor.add_mag`` of
        the tile's summed 3-D displacement magnitude per marker (n,)."""
        n, R, rank, F = rk.n, rk.R, C.shape[1], B.shape[0] // 3
        mm = self.marker_major
        for t in starts:
            m = min(self.m, F - t)
            rows = slice(3 * t, 3 * (t + m))
            order = (2, 1, 0) if mm else (1, 0, 2)   # from (frames, 3, columns)
            E = self.E[:3 * m * n].reshape((n, 3, m) if mm else (3, m, n))
            E[...] = B[rows, cols].reshape(m, 3, n).transpose(order)
            Cm = self.C[:3 * m * rank].reshape((rank, 3, m) if mm else (3, m, rank))
            Cm[...] = C[rows].reshape(m, 3, rank).transpose(order)
            step = self.step[:3 * m * n].reshape(E.shape)
            D2 = self.D2[:m * n].reshape((n, m) if mm else (m, n))
            sq = ("jcf,jcf->jf", "cfj,cfj->fj")[not mm]
            if mag:
                d = np.sqrt(np.einsum(sq, E, E, out=D2))
                visitor.add_mag(d.sum(axis=1) if mm else np.einsum("fj->j", d))
            for k in range(1, rank + 1):
                # E^(k) = E^(k-1) - C[:, k-1] R[k-1, :]   (secondary markers only)
                if mm:
                    Es, rc, out = E[k:], np.multiply(R[k - 1, k:, None, None], Cm[k - 1],
                                                     out=step[k:]), D2[k:]
                else:
                    Es, rc, out = E[:, :, k:], np.multiply(Cm[:, :, k - 1, None], R[k - 1, k:],
                                                           out=step[:, :, k:]), D2[:, k:]
                np.subtract(Es, rc, out=Es)
                D2k = np.einsum(sq, Es, Es, out=out)
                visitor.visit(k, D2k.T if mm else D2k)


def _passes(rk: MarkerRanking, blocks, labels, rank: int, visitors: list,
            mag: bool = False) -> None:
    """One pass over the blocks, each block's tiles shared out among ``len(visitors)``
    threads (tile i to thread i mod threads; :meth:`_Tiles.run` with visitor i)."""
    threads = len(visitors)
    tiles = [_Tiles(rk.n, rank) for _ in range(threads)]
    R = rk.R
    with ThreadPoolExecutor(threads) if threads > 1 else contextlib.nullcontext() as pool:
        for B in blocks():
            B, cols = _pivot_columns(rk, B, labels)
            C = scipy.linalg.solve_triangular(R[:rank, :rank], B[:, cols[:rank]].T,
                                              trans="T").T
            starts = range(0, B.shape[0] // 3, tiles[0].m)
            if pool is None:
                tiles[0].run(rk, B, cols, C, starts, visitors[0], mag)
                continue
            jobs = [pool.submit(tiles[i].run, rk, B, cols, C, starts[i::threads],
                                visitors[i], mag) for i in range(threads)]
            for job in jobs:
                job.result()


def _like(buf: np.ndarray, a: np.ndarray) -> np.ndarray:
    """A view of ``buf`` shaped as the 2-D ``a``, in ``a``'s memory order."""
    if a.strides[0] < a.strides[1]:
        return buf[:a.size].reshape(a.shape[::-1]).T
    return buf[:a.size].reshape(a.shape)


class _Sample:
    """One thread's sample of each k's D2 values (at most ``cap`` values per k): one value in
    ``rate``, drawn uniformly within each tile; when full, every second value is kept and the
    rate doubles."""

    def __init__(self, rank: int, seed: int, cap: int):
        self.values: list[list[np.ndarray]] = [[] for _ in range(rank + 1)]
        self.count = np.zeros(rank + 1, dtype=np.int64)     # values seen
        self.sampled = np.zeros(rank + 1, dtype=np.int64)
        self.rate = np.ones(rank + 1)
        self.carry = np.zeros(rank + 1)
        self.cap = cap
        self.rng = np.random.default_rng([0, seed])

    def visit(self, k: int, D2: np.ndarray) -> None:
        self.count[k] += D2.size
        want = self.carry[k] + D2.size / self.rate[k]
        take = int(want)
        self.carry[k] = want - take
        if take:
            at = self.rng.integers(0, D2.size, take)
            self.values[k].append(D2[at // D2.shape[1], at % D2.shape[1]])
            self.sampled[k] += take
        if self.sampled[k] > self.cap:
            self.values[k] = [np.concatenate(self.values[k])[::2].copy()]
            self.sampled[k] = self.values[k][0].size
            self.rate[k] *= 2


class _Sums:
    """One thread's running sums, count and maximum of each k (and its probes' visits)."""

    def __init__(self, n: int, rank: int, probes: dict[int, list[_Probe]], i: int):
        self.sq = np.zeros(rank + 1)
        self.cnt = np.zeros(rank + 1, dtype=np.int64)
        self.top = np.zeros(rank + 1)                      # max D2
        self.per_marker = [np.zeros(n - k) for k in range(rank + 1)]
        self.mag = np.zeros(n)
        self.buf = np.empty(n * _tile_frames(n))
        self.probes, self.i = probes, i

    def add_mag(self, mag: np.ndarray) -> None:
        self.mag += mag

    def visit(self, k: int, D2: np.ndarray) -> None:
        self.sq[k] += D2.sum()
        self.cnt[k] += D2.size
        self.top[k] = max(self.top[k], D2.max())
        dist = np.sqrt(D2, out=_like(self.buf, D2))
        self.per_marker[k] += np.einsum("fj->j", dist)
        for p in self.probes.get(k, ()):
            p.visit(D2, self.i)

    @classmethod
    def merged(cls, parts: list[_Sums]) -> _Sums:
        """The threads' sums added, in thread order."""
        s = parts[0]
        for p in parts[1:]:
            s.sq += p.sq
            s.cnt += p.cnt
            s.top = np.maximum(s.top, p.top)
            s.mag += p.mag
            for k in range(1, len(s.per_marker)):
                s.per_marker[k] += p.per_marker[k]
        return s


def streamed_error_curve(train_ranking: MarkerRanking,
                         blocks: Callable[[], Iterable[np.ndarray]], labels: Sequence[str],
                         k_max: int | None = None, threads: int = 1) -> pd.DataFrame:
    """:func:`~facemotion.regions.prediction.error_curve` of the held-out rows that
    ``blocks()`` yields (each call a fresh pass; blocks of whole frames, columns ``labels``).
    ``threads``: threads sharing each block's tiles (the sums are then added in another order:
    the means agree to round-off; the median and the maximum are the same numbers)."""
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise InputError(f"threads: must be a positive integer, got {threads!r}")
    rk = train_ranking
    n, rank = rk.n, _k_stop(rk, k_max)
    cap = max(16, KEEP_BYTES // 8 // max(rank, 1))
    # BLAS on one thread: its work here (C of each block) is small, and its threads would
    # wait on the tiles' threads
    with threadpool_limits(1, user_api="blas"):
        probes = _first_probes(_pilot(rk, blocks, labels, rank, threads), rank, cap, threads)
        parts = [_Sums(n, rank, probes, i) for i in range(threads)]
        _passes(rk, blocks, labels, rank, parts, mag=True)
        s = _Sums.merged(parts)
        medians = _medians(rk, blocks, labels, rank, s.cnt, probes, threads)
    lab = rk.labels_in_order
    out = []
    for k in range(1, rank + 1):
        total = float(s.per_marker[k].sum())
        m = s.mag[k:]
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = float((s.per_marker[k] / m).mean())
        out.append({
            "k": k, "mean_abs_error_mm": total / s.cnt[k],
            "rms_error_mm": float(np.sqrt(s.sq[k] / s.cnt[k] / 3.0)),
            "median_abs_error_mm": medians[k], "max_abs_error_mm": float(np.sqrt(s.top[k])),
            "rel_error_per_marker": rel,
            "rel_error_pooled": total / float(m.sum()) if m.sum() > 0 else float("nan"),
            "pivot_marker": lab[k - 1], "main_markers": ",".join(lab[:k]),
        })
    out.append(_zero_row(n, lab))
    return pd.DataFrame(out, columns=CURVE_COLUMNS)


def _pilot(rk, blocks, labels, rank: int, threads: int) -> list[_Sample]:
    """The pilot pass: every PILOT_EVERY-th frame of each block, each k's D2 sampled."""
    def thinned():
        for B in blocks():
            B = np.asarray(B)
            yield B.reshape(-1, 3, B.shape[1])[::PILOT_EVERY].reshape(-1, B.shape[1])

    cap = max(1024, SAMPLE_BYTES // 8 // max(rank, 1) // threads)
    parts = [_Sample(rank, i, cap) for i in range(threads)]
    _passes(rk, thinned, labels, rank, parts)
    return parts


class _Probe:
    """Order statistics (0-based ``ranks`` among a k's values) sought in the D2 values whose
    bit patterns lie in [lo, hi]; ``below``: the values under lo (None: to count), ``inside``:
    the values in [lo, hi] (None: to count). A pass counts the values inside in MEDIAN_BINS
    equal ranges of bit patterns and, unless they are known to be too many, keeps them, up to
    ``cap`` values in all (``cap // threads`` a thread). Each thread adds into its own counts
    and lists (index ``i``)."""

    def __init__(self, ranks, lo, hi, cap, threads, below=None, inside=None):
        self.ranks, self.lo, self.hi, self.cap = list(ranks or ()), lo, hi, cap
        self.threads, self.below, self.inside = threads, below, inside
        self.room = cap // threads if inside is None or inside <= cap // threads else -1
        self.n_below, self.n_inside = [0] * threads, [0] * threads
        self.kept: list[list[np.ndarray]] = [[] for _ in range(threads)]
        self.width = (hi - lo) // MEDIAN_BINS + 1
        self.bins = np.zeros((threads, MEDIAN_BINS), dtype=np.int64)

    def visit(self, D2: np.ndarray, i: int) -> None:
        bits = D2.view(np.int64)
        if self.below is None:
            self.n_below[i] += int(np.count_nonzero(bits < self.lo))
        inside = (bits >= self.lo) & (bits <= self.hi)
        vals = D2[inside]
        self.n_inside[i] += vals.size
        self.bins[i] += np.bincount((vals.view(np.int64) - self.lo) // self.width,
                                    minlength=MEDIAN_BINS)
        if self.n_inside[i] <= self.room:
            self.kept[i].append(vals)
        else:
            self.kept[i] = []

    def after(self, total: int) -> tuple[list[float], list[_Probe]]:
        """After a pass: the D2 values found and the probes still to run: below or above the
        interval, or in the range of bit patterns holding the rank when the values inside
        were too many to keep."""
        below = sum(self.n_below) if self.below is None else self.below
        inside = sum(self.n_inside)
        kept = all(c <= self.room for c in self.n_inside)
        vals = np.concatenate([v for part in self.kept for v in part]) if kept else None
        bins = np.cumsum(self.bins.sum(axis=0))
        found, nxt = [], {}
        for r in self.ranks:
            if r < below:
                key = (0, self.lo - 1, 0, below)
            elif r >= below + inside:
                key = (self.hi + 1, _TOP, below + inside, total - below - inside)
            elif vals is not None:
                i = r - below
                found.append(float(np.partition(vals, i)[i]))
                continue
            else:   # too many to keep: the range that holds the rank
                b = int(np.searchsorted(bins, r - below, side="right"))
                lo = self.lo + b * self.width
                hi = min(self.hi, lo + self.width - 1)
                if lo == hi:   # one value
                    found.append(_value(lo))
                    continue
                before = int(bins[b - 1]) if b else 0
                key = (lo, hi, below + before, int(bins[b]) - before)
            nxt.setdefault(key, []).append(r)
        return found, [_Probe(rs, lo, hi, self.cap, self.threads, bf, ins)
                       for (lo, hi, bf, ins), rs in nxt.items()]


class _Visit:
    """Thread i's visitor of a median pass: each probe of k sees the tile's D2."""

    def __init__(self, probes: dict[int, list[_Probe]], i: int):
        self.probes, self.i = probes, i

    def visit(self, k: int, D2: np.ndarray) -> None:
        for p in self.probes.get(k, ()):
            p.visit(D2, self.i)


def _value(bits: int) -> float:
    """The float64 whose bit pattern is ``bits``."""
    return float(np.array(bits, dtype=np.int64).view(np.float64))


def _first_probes(pilot: list[_Sample], rank: int, cap: int, threads: int
                  ) -> dict[int, list[_Probe]]:
    """Each k's first interval of D2 for its middle order statistic(s): the pilot sample's
    quantiles around the middle, widened by SAMPLE_Z standard errors, and so that the values
    in it, expected, fill at most a quarter of ``cap`` (else more passes than memory)."""
    probes = {}
    for k in range(1, rank + 1):
        S = np.sort(np.concatenate([v for part in pilot for v in part.values[k]]))
        m = S.size
        expected = PILOT_EVERY * sum(int(part.count[k]) for part in pilot)
        half = min(SAMPLE_Z * np.sqrt(m * 0.25) + 2, max(2.0, 0.25 * cap * m / expected))
        i0, i1 = int(np.floor(m / 2 - half)), int(np.ceil(m / 2 + half))
        lo = 0 if i0 <= 0 else int(S[i0:i0 + 1].view(np.int64)[0])
        hi = _TOP if i1 >= m else int(S[i1:i1 + 1].view(np.int64)[0])
        probes[k] = [_Probe(None, lo, hi, cap, threads)]
    return probes


def _medians(rk, blocks, labels, rank, cnt, probes, threads: int) -> dict[int, float]:
    """Each k's exact median distance by selection among the D2 values (module notes), from
    the first probes, run in the main pass; further passes while any probe misses."""
    found: dict[int, list[float]] = {k: [] for k in probes}
    for k, (p,) in probes.items():
        h = int(cnt[k]) // 2
        p.ranks = [h] if cnt[k] % 2 else [h - 1, h]
    for _ in range(MAX_PASSES):
        nxt: dict[int, list[_Probe]] = {}
        for k, ps in probes.items():
            for p in ps:
                vals, more = p.after(int(cnt[k]))
                found[k] += vals
                if more:
                    nxt.setdefault(k, []).extend(more)
        probes = nxt
        if not probes:
            break
        # every k to ``rank`` again, as in the main pass: C from the same solve, so that each
        # pass recomputes the very same D2 values
        _passes(rk, blocks, labels, rank, [_Visit(probes, i) for i in range(threads)])
    else:
        raise RuntimeError(f"streamed error curve: the medians of k = {sorted(probes)} not "
                           f"selected in {MAX_PASSES} passes (the blocks differ between passes?)")
    out = {}
    for k, vals in found.items():
        d = [float(np.sqrt(v)) for v in sorted(vals)]
        out[k] = d[0] if len(d) == 1 else (d[0] + d[1]) / 2.0
    return out
