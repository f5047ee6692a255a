"""The sheet's ``copy_markers`` (:mod:`facemotion.ingest.copy_fill`) in a streamed load: the same
offsets and copies as :func:`~facemotion.ingest.copy_fill.copy_fill` of the whole takes, from
the first pass's masks and a few frames read back.

* A take's offset o = p_t - p_s (head coordinates) at its first frame with both markers
  measured: the first pass's masks find that frame; the frame alone is read back from the
  take's scratch file and aligned to the head reference (each frame's alignment depends on that
  frame only).
* Only when a take has no such frame: the median of p_t - p_s over every frame of every take of
  the dataset where both are measured (:func:`pooled_medians`). The pair's and the head
  markers' columns are read back in blocks of frames and aligned: a few markers of every frame,
  never a whole take. A scattered load computes these medians once, from what each take's scan
  kept (:func:`pair_differences` per take, then :func:`median_of_differences`).
* In the second pass each window of frames, once aligned, gets the copies
  (:func:`~facemotion.ingest.copy_fill.copy_rows`) before its gaps are filled; the gaps the
  plan sees are those left after the copy: the target missing where the source is missing too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facemotion.ingest.copy_fill import copy_rows, pair_columns, take_offsets
from facemotion.ingest.stream_scan import TakeScan


def _aligned(points: np.ndarray, labels: list[str], rate: float, head_markers: list[str],
             reference) -> np.ndarray:
    from facemotion.ingest.head_motion import align_head
    from facemotion.io.recording import Recording

    if not head_markers:
        return points
    return align_head(Recording(list(labels), points, rate), head_markers,
                      reference=reference)[0].points


def pair_points(scan: TakeScan, pairs: list[tuple[str, str]], head_markers: list[str],
                block_frames: int) -> list[np.ndarray]:
    """Per pair, its target's, source's and the head markers' points in every frame of the
    take (frames, 2 + head, 3; outliers NaN; the order of :func:`pair_names`), read back from
    the take's scratch file in blocks of frames."""
    out = []
    for pair in pairs:
        cols = [scan.labels.index(m) for m in pair_names(pair, head_markers)]
        pts = scan.columns(cols, block_frames)
        pts[scan.outliers[:, cols]] = np.nan
        out.append(pts)
    return out


def pair_names(pair: tuple[str, str], head_markers: list[str]) -> list[str]:
    return list(pair) + [h for h in head_markers if h not in pair]


def differences(points: np.ndarray, pair: tuple[str, str], rate: float,
                head_markers: list[str], reference) -> np.ndarray:
    """p_t - p_s (head coordinates) in the frames of ``points`` (:func:`pair_points`' layout)
    where both are measured."""
    pts = _aligned(points, pair_names(pair, head_markers), rate, head_markers, reference)
    both = np.isfinite(pts[:, :2]).all(axis=(1, 2))
    return pts[both, 0] - pts[both, 1]


def pair_differences(scan: TakeScan, pairs: list[tuple[str, str]], head_markers: list[str],
                     reference, block_frames: int) -> list[np.ndarray]:
    """Per pair, :func:`differences` over every frame of the take."""
    return [differences(pts, pair, scan.rate, head_markers, reference) for pair, pts in
            zip(pairs, pair_points(scan, pairs, head_markers, block_frames), strict=True)]


def median_of_differences(per_take: list[list[np.ndarray]]) -> list[np.ndarray | None]:
    """Per pair, the median over every take's differences (None when there are none)."""
    medians = []
    for j in range(len(per_take[0]) if per_take else 0):
        pooled = np.concatenate([d[j] for d in per_take])
        medians.append(np.median(pooled, axis=0) if pooled.size else None)
    return medians


@dataclass(frozen=True)
class CopyPlan:
    """The copies of a streamed dataset: the pairs' columns among the scans' markers (``used``)
    and the analysed ones (``keep``), and each take's offsets (one per pair)."""

    pairs: list[tuple[str, str]]
    used_cols: list[tuple[int, int]]
    keep_cols: list[tuple[int, int]]
    offsets: list[list[np.ndarray]]

    @classmethod
    def of(cls, scans: list[TakeScan], pairs: list[tuple[str, str]], keep: list[str], *,
           head_markers: list[str], reference, block_frames: int, where: str,
           pooled: np.ndarray | None = None) -> CopyPlan:
        """``pooled``: the pairs' medians over the whole dataset (pairs, 3; NaN: never
        measured together) when these scans are a part of it (a scattered load:
        :func:`facemotion.ingest.scatter.gather_copy_medians`); computed from the scans when a
        take needs them."""
        keep_cols = pair_columns(keep, pairs, where, scans[0].source)
        used_cols = [(scans[0].labels.index(t), scans[0].labels.index(s)) for t, s in pairs]
        per_take: list[list[np.ndarray]] = [[] for _ in scans]
        medians = None
        for j, ((t, s), (it, is_)) in enumerate(zip(pairs, used_cols, strict=True)):
            firsts = []
            for scan in scans:
                ok = ~(scan.missing | scan.outliers)
                f = np.flatnonzero(ok[:, it] & ok[:, is_])
                if f.size == 0:
                    firsts.append(None)
                    continue
                p = _aligned(scan.points(f[0], f[0] + 1), scan.labels, scan.rate,
                             head_markers, reference)
                firsts.append(p[0, it] - p[0, is_])

            def median(j=j):
                nonlocal medians
                if pooled is not None:
                    return None if np.isnan(pooled[j]).any() else pooled[j]
                if medians is None:
                    medians = median_of_differences([
                        pair_differences(sc, pairs, head_markers, reference, block_frames)
                        for sc in scans])
                return medians[j]

            for k, o in enumerate(take_offsets(firsts, median, (t, s), where)):
                per_take[k].append(o)
        return cls(list(pairs), used_cols, keep_cols, per_take)

    def copy(self, take: int, points: np.ndarray) -> None:
        """The copies into a window of take ``take`` (frames, used markers, 3), in place."""
        for (jt, js), o in zip(self.used_cols, self.offsets[take], strict=True):
            copy_rows(points, jt, js, o)

    def left_missing(self, miss: np.ndarray) -> np.ndarray:
        """The missing mask (frames, analysed markers) after the copies."""
        out = miss.copy()
        for jt, js in self.keep_cols:
            out[:, jt] &= miss[:, js]
        return out
