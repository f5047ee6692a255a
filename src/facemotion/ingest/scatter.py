"""A streamed dataset scattered over jobs, one take (file) per job, and gathered.

The takes of a dataset depend on each other only through the head reference (the median head
over every sentence, :func:`facemotion.ingest.streaming.reference_from_heads`) and the
copy_markers offsets. So a dataset loads in four steps, two of them one job per take (the
workflow's rules, or any scheduler); :func:`plan` says which sentences each take holds:

1. :func:`scan_heads` (per take): the take read in blocks and checked, each of its sentences
   on its own; their head markers' points (outliers removed) and the copy_markers pairs'
   points saved, small files;
2. :func:`gather_reference`: the head reference from every sentence's head points, in the
   dataset's order (and :func:`gather_copy_medians`: the pairs' median offsets);
3. :func:`load_take` (per take): its sentences streamed with that reference
   (:func:`facemotion.ingest.streaming.stream_dataset`): their rows of A (a displacements
   file), the Gram of its training sentences' rows, its gap report and sentences rows;
4. :func:`gather_gram`: G = the sum of the takes' Grams (the single job's G to round-off: the
   same rows, summed in another order).

The held-out sentences' rows then give the held-out error curve block by block
(:func:`heldout_blocks` for :func:`facemotion.regions.streamed_curve.streamed_error_curve`).

The cross-take face-shape check (:func:`facemotion.ingest.validation.check_same_shape`) needs
the first sentence's median face beside every other and is not run by a scattered load; the
single-job streamed load runs it.
"""

from __future__ import annotations

from dataclasses import dataclass
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


@dataclass(frozen=True)
class TakePart:
    """One take's job: its file, its sentences of the dataset (None: the whole take, one
    sentence), their roles and their places in the dataset's order (training, then held out)."""

    take: str
    sentences: list | None
    roles: list[str]
    positions: list[int]

    @property
    def train(self) -> list[int]:
        return [i for i, r in enumerate(self.roles) if r == "train"]

    @property
    def heldout(self) -> list[int]:
        return [i for i, r in enumerate(self.roles) if r == "heldout"]


def plan(sentences: list, roles: list[str]) -> list[TakePart]:
    """The takes of a dataset's ``sentences`` (:class:`~facemotion.ingest.segments.Segment`,
    in the dataset's order, with their ``roles``), each with its sentences in that order, the
    takes in the order they first appear."""
    parts: dict[str, list[int]] = {}
    for i, seg in enumerate(sentences):
        parts.setdefault(seg.take, []).append(i)
    return [TakePart(take, None if all(sentences[i].whole for i in idx)
                     else [sentences[i] for i in idx], [roles[i] for i in idx], idx)
            for take, idx in parts.items()]


def scan_heads(take: str, fmt: str, used: list[str], head_markers: list[str], *,
               sentences: list | None = None, limits: Limits | None = None,
               units: str | None = None, subject_prefix: str | None = None, scratch_dir=None,
               max_gib: float = MAX_GIB, copy_markers=(), rate: float | None = None
               ) -> tuple[list[np.ndarray | None], float, list[list[np.ndarray]]]:
    """Step 1 for one take: per sentence (``sentences`` of the take, default the whole take)
    its head markers' points (frames, head, 3; outliers NaN; None without head markers); the
    rate; per sentence, per copy_markers pair,
    :func:`facemotion.ingest.copy_windows.pair_points`."""
    import tempfile

    from facemotion.ingest.stream_scan import scan_sentences

    budget = Budget.of(max_gib, len(used))
    opts = dict(units=units, subject_prefix=subject_prefix, head_markers=list(head_markers),
                block_bytes=budget.text_bytes, rate=rate)
    with tempfile.TemporaryDirectory(dir=scratch_dir) as tmp:
        scratch = Path(tmp) / "take.f8"
        if sentences is None:
            scans = [scan_take(take, fmt, used, limits or Limits(), scratch, **opts)]
        else:
            scans = scan_sentences(take, fmt, sentences, [""] * len(sentences), used,
                                   limits or Limits(), scratch, **opts)
        pairs = [pair_points(s, list(copy_markers), list(head_markers), budget.frames)
                 for s in scans]
    return [s.head for s in scans], scans[0].rate, pairs


def heads_arrays(heads: list, rate: float, pairs: list[list[np.ndarray]],
                 positions: list[int]) -> dict[str, np.ndarray]:
    """Step 1's result for one take as the arrays of its file (read by :func:`by_position`)."""
    arrays = {"rate": np.array(rate), "positions": np.array(positions, dtype=np.int64)}
    for i, (head, pts) in enumerate(zip(heads, pairs, strict=True)):
        if head is not None:
            arrays[f"head{i}"] = head
        for j, p in enumerate(pts):
            arrays[f"pair{i}_{j}"] = p
    return arrays


def by_position(takes: list, n_pairs: int) -> tuple[list, list[list[np.ndarray]], list[float]]:
    """Every take's step-1 arrays (:func:`heads_arrays`) -> every sentence's head points and
    pairs' points in the dataset's order, and the takes' rates."""
    found, rates = {}, []
    for f in takes:
        rates.append(float(f["rate"]))
        for i, pos in enumerate(f["positions"]):
            found[int(pos)] = (f[f"head{i}"] if f"head{i}" in f else None,
                               [f[f"pair{i}_{j}"] for j in range(n_pairs)])
    order = sorted(found)
    if order != list(range(len(order))):
        raise InputError(f"gather: the takes hold sentences {order}, not 0..{len(order) - 1}")
    return [found[k][0] for k in order], [found[k][1] for k in order], rates


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


def load_take(part: TakePart, fmt: str, out, *, head_reference: np.ndarray | None,
              **options) -> StreamedDataset:
    """Step 3 for one take: its sentences' displacements file ``out`` and the Gram of its
    training sentences' rows (``gram``; zeros when it has none)."""
    return stream_dataset([part.take], fmt, out, sentences=part.sentences, train=part.train,
                          heldout=part.heldout, head_reference=head_reference, **options)


def gather_gram(grams: list[np.ndarray], train_rows: list[int]) -> np.ndarray:
    """Step 4: G = the sum of the takes' Grams (each of its training rows), in the dataset's
    order."""
    if len(grams) != len(train_rows):
        raise InputError(f"gather_gram: {len(grams)} Gram matrices for {len(train_rows)} takes")
    if not any(train_rows):
        raise InputError("gather_gram: no training sentence")
    G = np.zeros_like(np.asarray(grams[0], dtype=float))
    for g, rows in zip(grams, train_rows, strict=True):
        if g.shape != G.shape:
            raise InputError(f"gather_gram: Gram matrices of shapes {G.shape} and {g.shape}")
        if rows:
            G += g
    return G


def heldout_blocks(parts: list[tuple], block_rows: int | None = None):
    """The held-out rows of the takes' displacements files, ``parts`` = [(path, sentence
    indices in that file)], as a callable that yields them in blocks of whole frames, a fresh
    pass each call (what :func:`facemotion.regions.streamed_curve.streamed_error_curve`
    reads)."""
    from facemotion.ingest.displacement_file import open_displacements

    files = [(open_displacements(p), idx) for p, idx in parts if len(idx)]
    if not files:
        raise InputError("heldout_blocks: no held-out sentence")
    first = files[0][0]
    for f, _ in files[1:]:
        if list(f.labels) != list(first.labels):
            raise InputError(f"{f.path}: markers differ from {first.path}")

    def blocks():
        for f, idx in files:
            yield from f.rows(idx).blocks(block_rows)
    return blocks
