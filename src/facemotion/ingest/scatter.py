"""A streamed dataset scattered over jobs, one take per job, and gathered.

The takes of a dataset depend on each other only through the head reference (the median head
over every take, :func:`facemotion.ingest.streaming.reference_from_heads`). So a dataset loads
in four steps, two of them one job per take (the workflow's rules, or any scheduler):

1. :func:`scan_heads` (per take): the take read in blocks and checked; its head markers'
   points (outliers removed) saved, a small file;
2. :func:`gather_reference`: the head reference from every take's head points (and
   :func:`gather_copy_medians`: the copy_markers pairs' median offsets over every take);
3. :func:`load_take` (per take): the take streamed with that reference
   (:func:`facemotion.ingest.streaming.stream_dataset`): its part of A (a displacements file),
   its rows' Gram A_t^T A_t, its gap report and sentences row;
4. :func:`gather_gram`: G = sum of the training takes' Grams (equal to the single job's G to
   round-off: the same rows, summed in another order).

The held-out takes' parts of A then give the held-out error curve block by block
(:func:`heldout_blocks` for :func:`facemotion.regions.streamed_curve.streamed_error_curve`).

The cross-take face-shape check (:func:`facemotion.ingest.validation.check_same_shape`) needs
the first take's median face beside every other take and is not run by a scattered load; the
single-job streamed load runs it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.ingest.copy_windows import differences, median_of_differences, pair_points
from facemotion.ingest.stream_scan import scan_take
from facemotion.ingest.streaming import (
    MAX_GIB,
    Budget,
    StreamedDataset,
    reference_from_heads,
    stream_dataset,
)
from facemotion.ingest.validation import Limits


def scan_heads(take: str, fmt: str, used: list[str], head_markers: list[str], *,
               limits: Limits | None = None, units: str | None = None,
               subject_prefix: str | None = None, scratch_dir=None,
               max_gib: float = MAX_GIB, copy_markers=()
               ) -> tuple[np.ndarray, float, list[np.ndarray]]:
    """Step 1 for one take: (its head markers' points (frames, head, 3), outliers NaN; rate;
    per copy_markers pair, :func:`facemotion.ingest.copy_windows.pair_points`)."""
    import tempfile

    budget = Budget.of(max_gib, len(used))
    with tempfile.TemporaryDirectory(dir=scratch_dir) as tmp:
        scan = scan_take(take, fmt, used, limits or Limits(), Path(tmp) / "take.f8",
                         units=units, subject_prefix=subject_prefix,
                         head_markers=list(head_markers), block_bytes=budget.text_bytes)
        pairs = pair_points(scan, list(copy_markers), list(head_markers), budget.frames)
    return scan.head, scan.rate, pairs


def gather_reference(heads: list[np.ndarray], rates: list[float], head_markers: list[str],
                     where: str) -> np.ndarray:
    """Step 2: the head reference of the dataset (its takes in the dataset's order)."""
    for r in rates[1:]:
        if r != rates[0]:
            raise InputError(f"{where}: the takes' frame rates differ ({rates[0]} and {r} Hz)")
    return reference_from_heads(heads, rates[0], list(head_markers), where)


def gather_copy_medians(pairs_points: list[list[np.ndarray]], copy_markers, rate: float,
                        head_markers: list[str], reference) -> np.ndarray:
    """Step 2, with copy_markers: each pair's median offset over every take (pairs, 3) from
    each take's :func:`scan_heads` pairs; a take without a frame where both are measured takes
    it (:mod:`facemotion.ingest.copy_windows`). A NaN row: a pair never measured together, an
    error in the job of a take that needs it."""
    medians = median_of_differences([
        [differences(pts, pair, rate, list(head_markers), reference)
         for pair, pts in zip(copy_markers, take, strict=True)] for take in pairs_points])
    return np.array([np.full(3, np.nan) if m is None else m for m in medians]).reshape(-1, 3)


def load_take(take: str, fmt: str, out, *, head_reference: np.ndarray | None,
              **options) -> StreamedDataset:
    """Step 3 for one take: its displacements file ``out`` and its rows' Gram (``gram``)."""
    return stream_dataset([take], fmt, out, train=[0], heldout=[],
                          head_reference=head_reference, **options)


def gather_gram(grams: list[np.ndarray], roles: list[str]) -> np.ndarray:
    """Step 4: G = sum over the training takes of their Grams, in the dataset's order."""
    if len(grams) != len(roles):
        raise InputError(f"gather_gram: {len(grams)} Gram matrices for {len(roles)} takes")
    train = [g for g, r in zip(grams, roles, strict=True) if r == "train"]
    if not train:
        raise InputError("gather_gram: no training take")
    G = np.array(train[0], dtype=float)
    for g in train[1:]:
        if g.shape != G.shape:
            raise InputError(f"gather_gram: Gram matrices of shapes {G.shape} and {g.shape}")
        G += g
    return G


def heldout_blocks(parts: list, block_rows: int | None = None):
    """The rows of the takes' displacements files ``parts`` (their order), as a callable that
    yields them in blocks of whole frames, a fresh pass each call (what
    :func:`facemotion.regions.streamed_curve.streamed_error_curve` reads)."""
    from facemotion.ingest.displacement_file import open_displacements

    files = [open_displacements(p) for p in parts]
    if not files:
        raise InputError("heldout_blocks: no held-out take")
    for f, p in zip(files[1:], parts[1:], strict=True):
        if list(f.labels) != list(files[0].labels):
            raise InputError(f"{p}: markers differ from {parts[0]}")

    def blocks():
        for f in files:
            yield from f.rows().blocks(block_rows)
    return blocks
