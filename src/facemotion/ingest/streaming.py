"""Takes streamed from file to the Gram matrix G = A^T A and the chunked A, in bounded memory.

The same path as :func:`facemotion.ingest.loading.load_dataset` (read -> check -> remove head
motion -> select markers -> fill gaps -> displacements), in two passes over each take, neither
holding a whole recording:

1. :func:`facemotion.ingest.stream_scan.scan_take`: the file read in blocks of lines, every
   check of the take run per block (or, where a check needs the whole take, on what the pass
   kept: see that module), the raw numbers of the markers used written to a scratch file;
2. after every take's first pass (the head reference is the median over all takes): each take
   read back from its scratch file in blocks of frames, each block aligned to the head
   reference (per frame, as :func:`facemotion.ingest.head_motion.align_head`), filled from a
   window around it (:mod:`facemotion.ingest.gap_windows`: the whole-take fill's values), turned
   into displacements from the take's neutral pose, written to the displacements file and added
   into G (the training sentences' rows: G = sum_b A_b^T A_b, the Gram route of
   :mod:`facemotion.ranking.gram`).

A load of one take without head markers (a take alone; each job of a scattered load) first
tries one pass (:class:`OnePass`): each block, once checked, goes straight to A and G while the
take has nothing to fix; the first block with a gap, an outlier or a step the speed screen
flags ends it (what was written is dropped) and the take is read again the two-pass way.

``max_gib`` (the workflow's setting ``memory.max_gib``) bounds the memory: it sets the
blocks' sizes, the log says the bound and the sizes, and a gap whose fill needs a window larger
than the bound is an error naming it.
``copy_markers`` are copied in each window after its alignment, from offsets found by
:mod:`facemotion.ingest.copy_windows`. Sentences cut from takes (``segments``): a take is read
once for all its sentences, each then checked and streamed on its own frames. Readers without
a block reader (formats other than TRC and Intel C3D, and files with a subject prefix) read
the take whole, then give it in blocks.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

# imported here, not where it is used: threadpool_limits (stream_dataset) limits only the BLAS
# libraries already loaded when it is entered
from scipy.linalg.blas import dsyrk
from threadpoolctl import threadpool_limits

from facemotion.errors import InputError
from facemotion.ingest.gap_windows import GapPlan, fill_window, plan_gaps
from facemotion.ingest.stream_scan import TakeScan, scan_take
from facemotion.ingest.validation import Limits

log = logging.getLogger("facemotion")

#: The default memory bound (GiB) of a streamed load.
MAX_GIB = 1.0
#: Below this many markers the Gram's BLAS runs on one thread: each block's G += B^T B is
#: then small, and a second thread mostly spins between blocks (measured: a third more CPU
#: time for 468 markers, no gain in wall time).
BLAS_ONE_THREAD_BELOW = 2000
#: Copies of a window's points alive at once in the second pass (points, aligned, filled,
#: displacements, their transposes): the bound is shared out by this.
WINDOW_COPIES = 10


@dataclass
class StreamedDataset:
    """A streamed dataset: the training rows' Gram matrix, the displacements file (A on disk),
    and the tables :func:`~facemotion.ingest.loading.load_dataset` gives."""

    gram: np.ndarray             # (n, n) G = A_train^T A_train
    train_rows: int
    labels: list[str]
    path: Path                   # the displacements file
    gap_report: pd.DataFrame
    sentences: pd.DataFrame
    missing: np.ndarray          # (F, n) bool, missing before filling
    filled: np.ndarray           # (F, n) bool


@dataclass(frozen=True)
class Budget:
    """Block sizes from the memory bound."""

    max_gib: float
    text_bytes: int              # text read per block in the first pass
    frames: int                  # frames per block in the second pass
    window_frames: int           # largest window a block may be filled from

    @classmethod
    def of(cls, max_gib: float, n_used: int) -> Budget:
        if not np.isfinite(max_gib) or max_gib <= 0:
            raise InputError(f"max_gib: must be positive, got {max_gib!r}")
        total = max_gib * 2**30
        text = int(min(16 * 2**20, max(2**20, total / 24)))
        per_frame = 24 * max(n_used, 1) * WINDOW_COPIES
        window = int(0.5 * total / per_frame)
        frames = max(16, min(window // 4, 8192))
        if window < 2 * frames:
            raise InputError(f"max_gib = {max_gib:g}: too small for {n_used} markers "
                             f"(a window of {window} frames)")
        return cls(max_gib, text, frames, window)


def _same_layout(paths: list[str], fmt: str, subject_prefix) -> list[str]:
    """Every take's labels (headers only for TRC) equal the first take's."""
    from facemotion.io.registry import read_labels

    first = read_labels(paths[0], fmt, subject_prefix)
    for p in paths[1:]:
        labels = read_labels(p, fmt, subject_prefix)
        if labels != first:
            extra = [m for m in labels if m not in first][:5]
            lacking = [m for m in first if m not in labels][:5]
            raise InputError(f"{p}: marker labels differ from {paths[0]}: "
                             + (f"not in it: {', '.join(extra)}; " if extra else "")
                             + (f"missing: {', '.join(lacking)}" if lacking
                                else "the same markers in another order"))
    return first


def reference_from_heads(heads: list[np.ndarray], rate: float, head_markers: list[str],
                         where: str) -> np.ndarray:
    """The head reference of :func:`facemotion.ingest.loading.remove_head_motion` from every
    take's head-marker points (frames, head, 3; outliers NaN), in the dataset's order: the
    median over all takes of the head aligned to the first take's first complete frame."""
    from facemotion.ingest.head_motion import align_head
    from facemotion.io.recording import Recording, finite_samples

    if len(head_markers) < 3:
        raise InputError(f"{where}: {len(head_markers)} head marker(s) given "
                         f"({', '.join(head_markers)}); at least 3 are needed")
    complete = np.flatnonzero(finite_samples(heads[0]).all(axis=1))
    if complete.size == 0:
        raise InputError(f"{where}: no frame has all head markers {', '.join(head_markers)}")
    first = heads[0][complete[0]]
    stacked = np.concatenate([
        align_head(Recording(list(head_markers), h, rate), head_markers, reference=first)[0].points
        for h in heads])
    return np.nanmedian(stacked, axis=0)


def head_reference(scans: list[TakeScan], head_markers: list[str], where: str,
                   reference: np.ndarray | None = None):
    """The head reference (``reference`` when given: a scattered load's, computed from all the
    takes) and each take's head-fit residuals, as
    :func:`facemotion.ingest.loading.remove_head_motion` computes them (the head markers only:
    their points are kept by the first pass)."""
    from facemotion.ingest.head_motion import align_head
    from facemotion.io.recording import Recording

    if reference is None:
        reference = reference_from_heads([s.head for s in scans], scans[0].rate, head_markers,
                                         where)
    heads = [Recording(list(head_markers), s.head, s.rate, s.source) for s in scans]
    residuals = []
    for h in heads:
        res = align_head(h, head_markers, reference=reference)[1]
        residuals.append(res)
        log.info("%s: head fit RMS residual mean %.3f mm, max %.3f mm", h.source,
                 float(np.mean(res)), float(np.max(res)))
    return reference, residuals


def same_shape(scans: list[TakeScan], limits: Limits, budget: Budget,
               max_frames: int = 200) -> list[float]:
    """:func:`facemotion.ingest.validation.check_same_shape` with the first take's median
    face taken exactly, column batch by column batch from its scratch file."""
    from facemotion.ingest.validation import _fit_rms, shape_verdict

    if len(scans) < 2:
        return [0.0]
    s0 = scans[0]
    n = len(s0.labels)
    per_col = max(1, int(budget.max_gib * 2**30 / 4 / (24 * s0.n_frames)))
    ref = np.empty((n, 3))
    for c in range(0, n, per_col):
        x = s0.columns(np.arange(c, min(n, c + per_col)), budget.frames)
        x[s0.outliers[:, c:c + per_col]] = np.nan
        x[~np.isfinite(x)] = np.nan
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a marker never seen: NaN here
            ref[c:c + per_col] = np.nanmedian(x, axis=0) if len(x) else np.nan
    cols = np.isfinite(ref).all(axis=1)
    idx = np.flatnonzero(cols)
    out = [0.0]
    for s in scans[1:]:
        ok = ~(s.missing | s.outliers)
        frames = np.flatnonzero(ok[:, cols].all(axis=1))
        if idx.size < 3 or frames.size == 0:
            out.append(float("nan"))
            continue
        frames = frames[np.linspace(0, frames.size - 1, min(frames.size, max_frames)).astype(int)]
        X = np.stack([s.points(f, f + 1)[0][cols] for f in frames])
        proper, mirror = (float(np.min(r)) for r in _fit_rms(X, ref[cols]))
        shape_verdict(proper, mirror, s.source, s0.source, limits)
        out.append(proper)
    return out


def _gram_add(G: np.ndarray, rows_t: np.ndarray) -> np.ndarray:
    """G += B^T B in place on G's upper triangle (BLAS dsyrk, no n x n temporary), from
    ``rows_t`` = B^T (markers, rows), C-ordered: B in Fortran order, the layout in which
    dsyrk's B^T B form runs fastest."""
    return dsyrk(1.0, rows_t.T, beta=1.0, c=G, trans=1, lower=0, overwrite_c=1)


class OnePass:
    """A take turned into displacements and added into G while it is read (its first pass),
    for a load of one take without head markers: right while the take has nothing to fix
    (no missing sample, no outlier, no step the speed screen flags), the rows, their order
    and their arithmetic those of :func:`stream_take`. :meth:`add` declines the first block
    that has something to fix; the caller then drops what was written and loads the take the
    two-pass way."""

    def __init__(self, out, labels: list[str], train: bool, neutral: str):
        self.out, self.labels, self.train, self.neutral = out, labels, train, neutral
        self.writer = None
        self.G = None
        self.n0 = None

    def add(self, blk: np.ndarray, a: int, n_frames: int, to_fix: bool) -> bool:
        """Block ``blk`` (frames from ``a``, markers as ``labels``) into A and G; False (and
        nothing kept) when it has something to fix."""
        if to_fix or (self.n0 is None and self.neutral != "first_frame" and len(blk) < 10
                      and a + len(blk) < n_frames):
            self.abort()
            return False
        if self.writer is None:
            from facemotion.ingest.displacement_file import DisplacementsWriter

            n = len(self.labels)
            self.writer = DisplacementsWriter(self.out, self.labels, 3 * n_frames)
            self.G = np.zeros((n, n), order="F") if self.train else None
            head = np.ascontiguousarray(blk[:10])  # the layout stream_take averages
            self.n0 = head[0].copy() if self.neutral == "first_frame" else head.mean(axis=0)
        rows_t = (blk.transpose(1, 0, 2) - self.n0[:, None, :]).reshape(len(self.labels), -1)
        self.writer.write_rows(rows_t.T)
        if self.G is not None:
            self.G = _gram_add(self.G, rows_t)
        return True

    def abort(self) -> None:
        if self.writer is not None:
            self.writer.abort()
        self.writer = self.G = self.n0 = None


def stream_take(scan: TakeScan, keep: list[str], plan: GapPlan, writer, G, budget: Budget,
                *, neutral: str, head_markers: list[str], reference, copy=None):
    """Pass 2 of one take: blocks aligned, copied into (``copy(points)``: the copy_markers,
    in place), filled, as displacements to ``writer`` and (when ``G`` is not None) into G.
    Returns the take's neutral pose (markers, 3) and G."""
    from facemotion.ingest.head_motion import align_head
    from facemotion.io.recording import Recording

    where = {m: i for i, m in enumerate(scan.labels)}
    cols = [where[m] for m in keep]
    n0 = None
    for a in range(0, scan.n_frames, budget.frames):
        b = min(scan.n_frames, a + budget.frames)
        lo, hi = plan.window(a, b)
        if hi - lo > budget.window_frames:
            raise InputError(f"{scan.source}: filling frames {a}-{b} needs a window of "
                             f"{hi - lo} frames (a long gap's model window), more than "
                             f"max_gib = {budget.max_gib:g} allows "
                             f"({budget.window_frames} frames): raise max_gib")
        pts = scan.points(lo, hi)
        if head_markers:
            rec = Recording(list(scan.labels), pts, scan.rate, scan.source)
            pts = align_head(rec, head_markers, reference=reference)[0].points
        if copy is not None:
            copy(pts)
        filled = fill_window(pts[:, cols], lo, a, b, plan, scan.rate, keep, scan.source)
        if n0 is None:
            n0 = filled[0].copy() if neutral == "first_frame" else filled[:10].mean(axis=0)
        # A's rows of these frames, transposed: (markers, frames x (x, y, z)), C-ordered
        rows_t = (filled.transpose(1, 0, 2) - n0[:, None, :]).reshape(len(keep), 3 * (b - a))
        del pts, filled
        writer.write_rows(rows_t.T)
        if G is not None:
            G = _gram_add(G, rows_t)
    return n0, G


def stream_dataset(recordings: list[str], fmt: str, out, *, units: str | None = None,
                   head_markers=(), exclude_markers=(), include_markers=(),
                   train: list[int], heldout: list[int], max_interp_s: float = 0.1,
                   long_gaps: str = "pca", neutral: str = "first_frame",
                   limits: Limits | None = None, sentences: list | None = None,
                   subject_prefix: str | None = None, copy_markers=(),
                   markers_named_in: str = "the subject sheet", rate: float | None = None,
                   max_gib: float = MAX_GIB,
                   head_reference: np.ndarray | None = None,
                   copy_medians: list | None = None) -> StreamedDataset:
    """:func:`~facemotion.ingest.loading.load_dataset`'s dataset, streamed (module notes): A
    written to the displacements file ``out``, the training rows' Gram returned.
    ``head_reference``: the head markers' reference (:func:`reference_from_heads` of every
    take of the dataset) when this call loads a part of it (one job of a scattered load), and
    ``rate``: the declared frame rate (the sheet's ``rate``), as
    :func:`~facemotion.ingest.loading.load_dataset` takes it.
    ``copy_medians`` the copy_markers pairs' medians over the whole dataset
    (:func:`facemotion.ingest.copy_windows.median_of_differences`)."""
    from facemotion.ingest.loading import check_marker_lists
    from facemotion.ingest.segments import Segment

    limits = limits or Limits()
    items = [Segment.from_param(s) for s in (sentences if sentences is not None
                                              else recordings)]
    chosen = [items[i] for i in list(train) + list(heldout)]
    roles = ["train"] * len(train) + ["heldout"] * len(heldout)
    where = chosen[0].take
    labels = _same_layout([s.take for s in chosen], fmt, subject_prefix)
    keep, used = check_marker_lists(labels, where, head_markers, exclude_markers,
                                    include_markers, markers_named_in)
    budget = Budget.of(max_gib, len(used))
    log.info("streamed load: memory bound max_gib = %g GiB: %d MiB of text per read, %d frames per "
             "block, windows up to %d frames", max_gib, budget.text_bytes >> 20,
             budget.frames, budget.window_frames)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        threads = threadpool_limits(1, user_api="blas") if len(keep) < BLAS_ONE_THREAD_BELOW \
            else contextlib.nullcontext()
        with threads:
            return _load(chosen, roles, fmt, keep, used, out, scratch, budget, limits,
                         units=units, subject_prefix=subject_prefix, rate=rate,
                         neutral=neutral,
                         head_markers=list(head_markers), where=where,
                         max_interp_s=max_interp_s, long_gaps=long_gaps,
                         head_reference=head_reference,
                         copies=(list(copy_markers), copy_medians))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _load(chosen, roles, fmt, keep, used, out, scratch, budget, limits, *, units,
          subject_prefix, rate, neutral, head_markers, where, max_interp_s, long_gaps,
          head_reference, copies) -> StreamedDataset:
    """Every take's first pass (or its one pass), then the second."""
    one = _one_pass(chosen[0].take, fmt, used, keep, out, scratch / "take0.f8", roles[0],
                    budget, limits, units=units, subject_prefix=subject_prefix, rate=rate,
                    neutral=neutral, head_markers=list(head_markers)
                    ) if len(chosen) == 1 and chosen[0].whole else None
    if one is not None:
        try:
            return _second_pass([one[0]], chosen, roles, keep, used, out, budget, limits,
                                head_markers=[], where=where, neutral=neutral,
                                max_interp_s=max_interp_s, long_gaps=long_gaps,
                                one_pass=one[1], copies=copies)
        except BaseException:
            one[1].abort()
            raise
    scans = _first_pass(chosen, roles, fmt, used, limits, scratch, budget, units=units,
                        subject_prefix=subject_prefix, rate=rate,
                        head_markers=list(head_markers))
    return _second_pass(scans, chosen, roles, keep, used, out, budget, limits,
                        head_markers=list(head_markers), where=where, neutral=neutral,
                        max_interp_s=max_interp_s, long_gaps=long_gaps,
                        reference=head_reference, copies=copies)


def _first_pass(chosen, roles, fmt, used, limits, scratch, budget, *, units, subject_prefix,
                rate, head_markers) -> list[TakeScan]:
    """Every take's first pass, in the dataset's order; a take cut into sentences is read
    once for all of its sentences (:func:`facemotion.ingest.stream_scan.scan_sentences`)."""
    from facemotion.ingest.stream_scan import scan_sentences

    takes = list(dict.fromkeys(s.take for s in chosen))
    scans: list[TakeScan | None] = [None] * len(chosen)
    opts = dict(units=units, subject_prefix=subject_prefix, head_markers=head_markers,
                block_bytes=budget.text_bytes, rate=rate)
    for k, take in enumerate(takes):
        log.info("reading %s (%d/%d, in blocks)", take, k + 1, len(takes))
        mine = [i for i, s in enumerate(chosen) if s.take == take]
        cut = [i for i in mine if not chosen[i].whole]
        for i in mine:
            if chosen[i].whole:
                scans[i] = scan_take(take, fmt, used, limits, scratch / f"take{i}.f8",
                                     role=roles[i], **opts)
        if cut:
            got = scan_sentences(take, fmt, [chosen[i] for i in cut], [roles[i] for i in cut],
                                 used, limits, scratch / f"cut{k}.f8", **opts)
            for i, scan in zip(cut, got, strict=True):
                scans[i] = scan
    return scans


def _one_pass(take, fmt, used, keep, out, scratch, role, budget, limits, *, units,
              subject_prefix, rate, neutral, head_markers):
    """(the scan, its :class:`OnePass`) when the one take loads in one pass, or None (head
    markers to align, or something to fix: logged)."""
    if head_markers or keep != used:
        return None
    log.info("reading %s (1/1, in blocks, in one pass while it has nothing to fix)", take)
    one = OnePass(out, keep, role == "train", neutral)
    try:
        scan = scan_take(take, fmt, used, limits, scratch, units=units,
                         subject_prefix=subject_prefix, role=role, rate=rate,
                         block_bytes=budget.text_bytes, one_pass=one)
    except BaseException:
        one.abort()
        raise
    if scan is None:
        log.info("%s: a gap, an outlier or a fast step: read again, in two passes", take)
        return None
    return scan, one


def _second_pass(scans, chosen, roles, keep, used, out, budget, limits, *, head_markers,
                 where, neutral, max_interp_s, long_gaps, reference=None,
                 one_pass: OnePass | None = None, copies=((), None)) -> StreamedDataset:
    """Checks across takes, the head reference, then every take to A and G (``one_pass``:
    the one take's A and G, made while it was read)."""
    from types import SimpleNamespace

    from facemotion.ingest.displacement_file import DisplacementsWriter
    from facemotion.ingest.gaps import gap_report
    from facemotion.ingest.loading import gap_report_table, report_copies, sentences_table

    for s in scans[1:]:
        if s.rate != scans[0].rate:
            raise InputError(f"{s.source}: frame rate {s.rate} Hz differs from "
                             f"{scans[0].source} ({scans[0].rate} Hz)")
    shape_rms = same_shape(scans, limits, budget)
    if head_markers:
        reference, residuals = head_reference(scans, head_markers, where, reference)
    else:
        reference, residuals = None, [np.zeros(s.n_frames) for s in scans]
    dropped = [m for m in used if m not in set(keep)]
    log.info("analysing %d of %d markers%s", len(keep), len(used),
             f"; left out: {', '.join(dropped)}" if dropped else "")
    where_used = {m: i for i, m in enumerate(used)}
    cols = [where_used[m] for m in keep]
    if cols == list(range(len(used))):
        cols = slice(None)  # every marker used is analysed: views, not copies
    n = len(keep)
    copy_plan = _copy_plan(scans, copies, keep, head_markers, reference, budget, where,
                           one_pass is not None)
    G = np.zeros((n, n), order="F")
    if one_pass is not None:
        writer, G = one_pass.writer, G if one_pass.G is None else one_pass.G
    else:
        writer = DisplacementsWriter(out, keep, 3 * sum(s.n_frames for s in scans))
    neutrals, missing, reports = [], [], []
    copied = {t: 0 for t, _ in copies[0]}
    try:
        for i, (s, role) in enumerate(zip(scans, roles, strict=True)):
            miss = (s.missing | s.outliers if s.outliers.any() else s.missing)[:, cols]
            left = miss if copy_plan is None else copy_plan.left_missing(miss)
            plan = plan_gaps(left, s.rate, max_interp_s, long_gaps, keep, s.source)
            if one_pass is not None:
                n0, g = one_pass.n0, None
            else:
                n0, g = stream_take(s, keep, plan, writer, G if role == "train" else None,
                                    budget, neutral=neutral, head_markers=head_markers,
                                    reference=reference,
                                    copy=None if copy_plan is None
                                    else (lambda pts, i=i: copy_plan.copy(i, pts)))
            G = G if g is None else g
            neutrals.append(n0)
            missing.append(miss)
            methods = ["+".join(m for m, u in (("cubic", c), ("pca", p)) if u) or "none"
                       for c, p in zip(plan.cubic, plan.pca, strict=True)]
            rec = SimpleNamespace(filled=miss, labels=keep, n_markers=n,
                                  n_frames=s.n_frames)
            report = gap_report(rec, methods=methods, missing=left)
            if copy_plan is not None:
                report = report_copies(report, miss, miss & ~left, keep, copies[0])
                for t, jt in zip(copied, (jt for jt, _ in copy_plan.keep_cols), strict=True):
                    copied[t] += int((miss[:, jt] & ~left[:, jt]).sum())
            reports.append(report)
        sn = np.stack(neutrals)
        F = [s.n_frames for s in scans]
        writer.close(sentences=np.array([c.name for c in chosen], dtype=str),
                     row_sentence=np.repeat(np.arange(len(F)), [3 * f for f in F]),
                     row_frame=np.concatenate([np.repeat(np.arange(f), 3) for f in F]),
                     rate=np.array(scans[0].rate), fill_mask=_joined(missing),
                     head_residual=np.concatenate(residuals), neutral=sn.mean(axis=0),
                     sentence_neutral=sn)
    except BaseException:
        writer.abort()
        raise
    for t, s in copies[0]:
        log.info("marker %s: %d missing samples filled by copying %s's displacement (head "
                 "coordinates)", t, copied[t], s)
    iu = np.triu_indices(n, 1)
    G[(iu[1], iu[0])] = G[iu]
    checks = [s.check for s in scans]
    recs = [SimpleNamespace(n_frames=s.n_frames, rate=s.rate) for s in scans]
    return StreamedDataset(
        gram=np.ascontiguousarray(G),
        train_rows=3 * sum(s.n_frames for s, r in zip(scans, roles, strict=True)
                           if r == "train"),
        labels=list(keep), path=out,
        gap_report=gap_report_table(reports, checks, cols),
        sentences=sentences_table(chosen, roles, recs, residuals, checks, shape_rms),
        missing=_joined(missing), filled=_joined(missing))


def _copy_plan(scans, copies, keep, head_markers, reference, budget, where, one_pass: bool):
    """The copy_markers' :class:`~facemotion.ingest.copy_windows.CopyPlan`, or None (no
    pairs; or a take loaded in one pass, which had nothing missing to copy into: its pairs'
    markers are only checked)."""
    from facemotion.ingest.copy_fill import pair_columns
    from facemotion.ingest.copy_windows import CopyPlan

    pairs, pooled = copies
    where = f"{where}: subject sheet's copy_markers"
    if not pairs:
        return None
    if one_pass:
        pair_columns(keep, pairs, where, scans[0].source)
        return None
    return CopyPlan.of(scans, pairs, keep, head_markers=head_markers, reference=reference,
                       block_frames=budget.frames, where=where, pooled=pooled)


def _joined(arrays: list[np.ndarray]) -> np.ndarray:
    """The arrays one after another (the array itself when there is one: no copy)."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)
