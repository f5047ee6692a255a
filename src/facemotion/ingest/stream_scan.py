"""The first pass of a streamed take: read in blocks, checked, kept as raw numbers on disk.

Every block of frames read from the file (:func:`take_blocks`) goes through the checks of
:func:`facemotion.ingest.validation.check_take`, on the markers the analysis uses, and is
appended to a scratch file of float64 (frames x markers x 3, mm) that the second pass
(:mod:`facemotion.ingest.streaming`) reads back at disk speed. What the checks need across
blocks is kept per take, never the points themselves:

* the face centre's distances: per frame, so computed per block (exact); the spread is the
  median over frames of the per-frame median distance, kept as one number per frame and its
  median taken at the end (exact, two-pass: (frames,) floats);
* samples far from the centre: per sample (exact, per block);
* jumps faster than ``max_speed_mm_s``: the speed between each marker's consecutive valid
  samples, carried across blocks (exact). A marker with such a jump needs the whole-take test
  (:func:`facemotion.ingest.validation._reachable`, which keeps the longest piece); that test
  runs after the pass on that marker's column read back from the scratch file (exact);
* whether any marker moves: each marker's first measured position, carried (exact);
* the outlier and missing masks (frames x markers, bool) and the head markers' points, which
  the head reference and the gap windows need.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from facemotion.errors import InputError
from facemotion.ingest.validation import (
    MAX_OUTLIER_FRACTION,
    Limits,
    TakeCheck,
    _median_markers,
    _reachable,
    centre_distances,
    check_header,
    check_spread_value,
    outlier_notes,
)
from facemotion.io.recording import finite_samples

log = logging.getLogger("facemotion")


class WholeTake:
    """A format without a block reader: the take read whole, then given in blocks (memory is
    the reader's, not bounded by the stream's setting)."""

    def __init__(self, path, fmt, units, subject_prefix, rate=None):
        from facemotion.io.registry import read_recording

        self.rec = read_recording(path, fmt, units=units, subject_prefix=subject_prefix,
                                  rate=rate)
        if self.rec.filled.any():
            raise InputError(f"{path}: the file flags samples as filled by its producer; the "
                             "streamed loader does not carry those flags: load it whole")
        self.path, self.labels, self.rate = Path(path), list(self.rec.labels), self.rec.rate
        self.n_frames, self.units = self.rec.n_frames, self.rec.units
        self.units_source = self.rec.units_source

    def blocks(self, block_bytes: int):
        step = max(1, block_bytes // max(1, 24 * len(self.labels)))
        for a in range(0, self.n_frames, step):
            yield a, self.rec.points[a:a + step]


def take_blocks(path, fmt: str, units: str | None = None, subject_prefix: str | None = None,
                rate: float | None = None):
    """The take's header and a ``blocks(block_bytes)`` iterator of (first frame, points):
    the block readers of TRC (:mod:`facemotion.io.trc_blocks`) and of Intel C3D
    (:mod:`facemotion.io.c3d_blocks`), else the take read whole (:class:`WholeTake`).
    ``rate``: the declared frame rate, as :func:`facemotion.io.registry.read_recording` takes
    it."""
    from facemotion.io.registry import FORMATS, check_rate

    src = None
    if fmt == "trc" and not subject_prefix:
        from facemotion.io.trc_blocks import open_trc_blocks

        src = open_trc_blocks(path, units)
    elif fmt == "c3d" and not subject_prefix:
        from facemotion.io.base import check_readable
        from facemotion.io.c3d import c3d_layout
        from facemotion.io.c3d_blocks import open_c3d_blocks

        if c3d_layout(check_readable(path)).processor == "Intel":
            src = open_c3d_blocks(path, units)
    if src is None:
        return WholeTake(path, fmt, units, subject_prefix, rate)
    if rate is not None:
        FORMATS[fmt].check_stated_rate(path, src.rate,
                                       check_rate(rate, f"{path} (declared rate)"))
    return src


@dataclass
class TakeScan:
    """What the first pass kept of one take (see the module notes)."""

    source: str
    labels: list[str]          # the markers used (analysed, then head markers)
    rate: float
    n_frames: int
    scratch: Path              # raw float64 (frames, markers, 3), outliers not yet removed
    outliers: np.ndarray       # (frames, markers) bool
    missing: np.ndarray        # (frames, markers) bool, missing in the file
    check: TakeCheck
    head: np.ndarray | None = field(default=None)  # (frames, head, 3), outliers NaN
    offset: int = 0            # the first frame's in the scratch file (a sentence of a take)

    def points(self, a: int = 0, b: int | None = None) -> np.ndarray:
        """Frames [a, b) from the scratch file, outliers NaN (a fresh array)."""
        b = self.n_frames if b is None else b
        out = read_frames(self.scratch, len(self.labels), self.offset + a, self.offset + b)
        bad = self.outliers[a:b]
        if bad.any():
            out[bad] = np.nan
        return out

    def columns(self, cols, block_frames: int) -> np.ndarray:
        """Markers ``cols`` of every frame (frames, len(cols), 3), raw (outliers kept)."""
        return read_columns(self.scratch, len(self.labels), self.n_frames, cols, block_frames,
                            self.offset)


def read_frames(scratch: Path, n: int, a: int, b: int) -> np.ndarray:
    """Frames [a, b) of a scratch file of (frames, n, 3) float64, by plain reads (a memory
    map would count every page it touched in the process's resident memory)."""
    with open(scratch, "rb") as fh:
        fh.seek(24 * n * a)
        out = np.fromfile(fh, dtype=np.float64, count=3 * n * (b - a))
    return out.reshape(b - a, n, 3)


def read_columns(scratch: Path, n: int, F: int, cols, block_frames: int,
                 start: int = 0) -> np.ndarray:
    """Markers ``cols`` of frames [start, start + F) (F, len(cols), 3), read in blocks of
    frames."""
    cols = np.asarray(cols, dtype=np.int64)
    out = np.empty((F, cols.size, 3))
    for a in range(0, F, block_frames):
        b = min(F, a + block_frames)
        out[a:b] = read_frames(scratch, n, start + a, start + b)[:, cols]
    return out


@dataclass
class _Running:
    """The per-take state the checks carry from block to block."""

    n: int
    vmax: float
    rate: float
    last_x: np.ndarray = None
    last_f: np.ndarray = None
    first: np.ndarray = None
    moved: bool = False
    any_ok: bool = False
    cut: np.ndarray = None
    far_max: np.ndarray = None
    step2_max: float = 0.0

    def __post_init__(self):
        self.step2_max = (self.vmax / self.rate) ** 2 * (1.0 - 1e-9)
        self.last_x = np.full((self.n, 3), np.nan)
        self.last_f = np.full(self.n, -1, dtype=np.int64)
        self.first = np.full((self.n, 3), np.nan)
        self.cut = np.zeros(self.n, dtype=bool)
        self.far_max = np.zeros(self.n)


def _steps_full(x: np.ndarray, cols: np.ndarray, a: int, st: _Running) -> None:
    """The speed screen of markers ``cols`` valid in every frame of the block (x: their
    points), vectorised: consecutive frames, and the link to each one's last valid sample
    before. A screen: a marker it flags gets the exact whole-take test after the pass
    (:func:`_fast_outliers`), so squared steps are compared with a bound a little under
    (max_speed / rate)^2, which no step at the limit passes by a rounding."""
    with np.errstate(invalid="ignore", over="ignore"):
        d = x[1:] - x[:-1]
        step2 = np.einsum("fnc,fnc->fn", d, d)
        st.cut[cols] |= np.any(~(step2 <= st.step2_max), axis=0)
        seen = st.last_f[cols] >= 0
        if seen.any():
            c = cols[seen]
            link = np.linalg.norm(x[0, seen] - st.last_x[c], axis=1) * st.rate / (a - st.last_f[c])
            st.cut[c] |= ~(link <= st.vmax)
    st.last_x[cols] = x[-1]
    st.last_f[cols] = a + len(x) - 1


def _block_checks(blk: np.ndarray, a: int, st: _Running, limits: Limits):
    """One block: (far (b, n) bool, per-frame median distance (b,) NaN where < 3 markers,
    missing (b, n)); updates the carried state (speed cuts, first positions, moves)."""
    ok = finite_samples(blk)
    dist, enough = centre_distances(SimpleNamespace(points=blk), ok)
    med = np.full(len(blk), np.nan)
    if enough.all():
        med = _median_markers(dist)[:, 0]
    elif enough.any():
        med[enough] = _median_markers(dist[enough])[:, 0]
    d0 = dist if enough.all() and ok.all() else np.nan_to_num(dist, nan=0.0)
    far = d0 > limits.max_distance_mm
    st.far_max = np.maximum(st.far_max, d0.max(axis=0))
    valid = ok & ~far
    full = valid.all(axis=0)
    if full.all():
        _steps_full(blk, np.arange(st.n), a, st)
    elif full.any():
        _steps_full(blk[:, full], np.flatnonzero(full), a, st)
    for j in np.flatnonzero(valid.any(axis=0) & ~full):
        idx = np.flatnonzero(valid[:, j])
        x = blk[idx, j]
        f = a + idx
        if st.last_f[j] >= 0:
            x = np.concatenate([st.last_x[j][None], x])
            f = np.concatenate([[st.last_f[j]], f])
        if len(f) >= 2 and not st.cut[j]:
            with np.errstate(invalid="ignore", over="ignore"):
                speed = np.linalg.norm(np.diff(x, axis=0), axis=1) * st.rate / np.diff(f)
            st.cut[j] = bool(np.any(~(speed <= st.vmax)))
        st.last_x[j], st.last_f[j] = x[-1], f[-1]
    _note_moves(blk, ok, st)
    return far, med, ~ok


def _note_moves(blk: np.ndarray, ok: np.ndarray, st: _Running) -> None:
    """Each marker's first measured position, and whether a sample differs from it."""
    new = ok.any(axis=0) & np.isnan(st.first[:, 0])
    for j in np.flatnonzero(new):
        st.first[j] = blk[int(np.argmax(ok[:, j])), j]
    if ok.any():
        st.any_ok = True
        with np.errstate(invalid="ignore"):
            st.moved = st.moved or bool(np.any(ok & (blk != st.first[None]).any(axis=2)))


def _fast_outliers(columns: np.ndarray, cut: np.ndarray, far: np.ndarray, missing: np.ndarray,
                   rate: float, vmax: float):
    """The whole-take reachability test on the markers ``cut`` (with a fast jump; their
    ``columns`` (F, len(cut), 3) read back)."""
    F, n = far.shape
    fast = np.zeros((F, n), dtype=bool)
    top = np.zeros(n)
    for k, j in enumerate(cut):
        col = columns[:, k]
        idx = np.flatnonzero(~missing[:, j] & ~far[:, j])
        if idx.size < 2:
            continue
        keep = _reachable(col[idx], idx, rate, vmax)
        fast[idx[~keep], j] = True
        if not keep.all():
            with np.errstate(invalid="ignore", over="ignore"):
                v = np.linalg.norm(np.diff(col[idx], axis=0), axis=1) * rate / np.diff(idx)
            top[j] = float(np.nanmax(v))
    return fast, top


def _read_pass(src, cols, st: _Running, limits: Limits, block_bytes: int, scratch,
               one_pass):
    """The blocks read and checked: (far, per-frame median distance, missing), each block's
    numbers appended to ``scratch``; or, with ``one_pass``, given to it instead, and None as
    soon as it declines one (nothing more is read)."""
    F, n = src.n_frames, st.n
    far = np.zeros((F, n), dtype=bool)
    missing = np.zeros((F, n), dtype=bool)
    med = np.full(F, np.nan)
    with open(scratch, "wb") if one_pass is None else contextlib.nullcontext() as out:
        for a, blk in src.blocks(block_bytes):
            if cols is not None:
                blk = np.ascontiguousarray(blk[:, cols])
            b = a + len(blk)
            far[a:b], med[a:b], missing[a:b] = _block_checks(blk, a, st, limits)
            if one_pass is None:
                out.write(blk.reshape(-1).view(np.uint8))
            elif not one_pass.add(blk, a, F, far[a:b].any() or missing[a:b].any()
                                  or st.cut.any()):
                return None
    return far, med, missing


def _open(path, fmt, used, units, subject_prefix, rate):
    """The take's block source, its header as a record, and the columns of ``used``."""
    src = take_blocks(path, fmt, units, subject_prefix, rate)
    where = str(src.path)
    rec = SimpleNamespace(source=where, rate=src.rate, n_frames=src.n_frames, units=src.units,
                          units_source=src.units_source)
    have = set(src.labels)
    missing_labels = [m for m in used if m not in have]
    if missing_labels:
        raise InputError(f"{where}: marker {missing_labels[0]!r} is not in the data")
    at = {m: i for i, m in enumerate(src.labels)}
    cols = np.array([at[m] for m in used])
    whole = np.array_equal(cols, np.arange(len(src.labels)))  # every marker: no copy
    return src, rec, None if whole else cols


@dataclass
class _Pass:
    """What one read of a take found, frame by frame (the take's frames)."""

    scratch: Path
    far: np.ndarray
    med: np.ndarray
    missing: np.ndarray
    st: _Running


def scan_take(path, fmt: str, used: list[str], limits: Limits, scratch: Path, *,
              units: str | None = None, subject_prefix: str | None = None,
              head_markers: list[str] = (), role: str = "",
              block_bytes: int = 32 * 2**20, one_pass=None,
              rate: float | None = None) -> TakeScan | None:
    """Pass 1 of one take: read in blocks, every check of ``check_take`` on the markers
    ``used``, the raw numbers appended to ``scratch`` (see the module notes).

    ``one_pass`` (:class:`facemotion.ingest.streaming.OnePass`): no scratch file; every
    block goes to ``one_pass.add`` while the take has no missing sample, no outlier and no
    step the speed screen flags. None when it declines a block: the take needs the two
    passes (the caller reads it again with a scratch file)."""
    src, rec, cols = _open(path, fmt, used, units, subject_prefix, rate)
    conflict = check_header(rec, limits, units, role)
    st = _Running(len(used), limits.max_speed_mm_s, src.rate)
    got = _read_pass(src, cols, st, limits, block_bytes, scratch, one_pass)
    if got is None:
        return None
    found = _Pass(Path(scratch), *got, st)
    return _finish(found, 0, src.n_frames, rec, conflict, used, limits, head_markers,
                   block_bytes, moved=(st.any_ok, st.moved))


def scan_sentences(path, fmt: str, sentences: list, roles: list[str], used: list[str],
                   limits: Limits, scratch: Path, *, units: str | None = None,
                   subject_prefix: str | None = None, head_markers: list[str] = (),
                   block_bytes: int = 32 * 2**20, rate: float | None = None
                   ) -> list[TakeScan]:
    """Pass 1 of the sentences ``sentences`` (:class:`~facemotion.ingest.segments.Segment`
    intervals) of one take: the take read once, in blocks, into ``scratch``; then each
    sentence checked as ``check_take`` checks the sentence cut from the take
    (:func:`~facemotion.ingest.segments.cut`): the per-frame findings are the take's, sliced;
    the speed test, the face's spread, whether anything moves and the outlier counts are the
    sentence's own."""
    from facemotion.ingest.segments import check_grid_fits_take, frame_range

    src, rec, cols = _open(path, fmt, used, units, subject_prefix, rate)
    where, F = rec.source, src.n_frames
    ranges = []
    for seg in sentences:  # every interval first, as the sentences are cut before any check
        at = f"{where} (sentence {seg.name!r})"
        if seg.grid_end_s is not None:
            check_grid_fits_take(seg.grid_end_s, F, src.rate, at)
        ranges.append(frame_range(float(seg.start_s), float(seg.end_s), src.rate, F, at))
    st = _Running(len(used), limits.max_speed_mm_s, src.rate)
    found = _Pass(Path(scratch), *_read_pass(src, cols, st, limits, block_bytes, scratch, None),
                  st)
    out = []
    for seg, role, (i0, i1) in zip(sentences, roles, ranges, strict=True):
        sub = SimpleNamespace(**{**vars(rec), "source": f"{where} [{seg.name}]",
                                 "n_frames": i1 - i0})
        conflict = check_header(sub, limits, units, role)
        out.append(_finish(found, i0, i1, sub, conflict, used, limits, head_markers,
                           block_bytes))
    return out


def _finish(found: _Pass, i0: int, i1: int, rec, conflict, used, limits: Limits,
            head_markers, block_bytes: int, moved=None) -> TakeScan:
    """The checks that need a whole take (or sentence: frames [i0, i1) of the pass), from what
    the pass kept: the exact speed test, the spread, whether anything moves, the outliers."""
    where, n, F = rec.source, len(used), i1 - i0
    far, missing = found.far[i0:i1], found.missing[i0:i1]
    step = max(1, block_bytes // (24 * n))
    cut = np.flatnonzero(found.st.cut)
    if cut.size:
        fast, top = _fast_outliers(
            read_columns(found.scratch, n, F, cut, step, i0), cut, far, missing, rec.rate,
            limits.max_speed_mm_s)
        outliers = far | fast
    else:  # no step the screen flags: no sample is too fast
        fast, top, outliers = np.zeros((F, n), dtype=bool), np.zeros(n), far
    spread = _check_spread(found.med[i0:i1], rec, limits)
    any_ok, moves = moved if moved is not None else _moves(found.scratch, n, i0, i1, step)
    if any_ok and not moves:
        raise InputError(f"{where}: no marker moves in this take (every sample equals the "
                         "marker's first): a frozen or placeholder take")
    far_max = found.st.far_max if moved is not None or not far.any() else \
        _far_max(found.scratch, n, i0, i1, step)
    notes = outlier_notes(outliers, far, fast, far_max, top, used, rec.rate, limits)
    measured = missing.size - int(np.count_nonzero(missing))
    if measured and outliers.sum() > MAX_OUTLIER_FRACTION * measured:
        raise InputError(f"{where}: {outliers.sum()} of the take's {measured} measured samples "
                         f"are outliers (more than {MAX_OUTLIER_FRACTION:.0%}; first: "
                         f"{notes[0]})")
    if notes:
        if limits.outliers == "error":
            raise InputError(f"{where}: {notes[0]} ({limits.name('outliers')} is 'error')")
        for note in notes:
            log.warning("%s: %s; treated as gaps", where, note)
    check = TakeCheck(outliers, rec.units, rec.units_source, conflict, spread)
    scan = TakeScan(where, list(used), rec.rate, F, found.scratch, outliers, missing, check,
                    offset=i0)
    if head_markers:
        hcols = [used.index(h) for h in head_markers]
        h = scan.columns(hcols, step)
        h[outliers[:, hcols]] = np.nan
        scan.head = h
    return scan


def _moves(scratch: Path, n: int, i0: int, i1: int, step: int) -> tuple[bool, bool]:
    """(any sample measured, any differs from its marker's first) in frames [i0, i1)."""
    st = _Running(n, np.inf, 1.0)
    for a in range(i0, i1, step):
        blk = read_frames(scratch, n, a, min(i1, a + step))
        _note_moves(blk, finite_samples(blk), st)
    return st.any_ok, st.moved


def _far_max(scratch: Path, n: int, i0: int, i1: int, step: int) -> np.ndarray:
    """Each marker's largest distance from the face centre in frames [i0, i1) (as
    :func:`_block_checks` measures it)."""
    top = np.zeros(n)
    for a in range(i0, i1, step):
        blk = read_frames(scratch, n, a, min(i1, a + step))
        ok = finite_samples(blk)
        dist, enough = centre_distances(SimpleNamespace(points=blk), ok)
        d0 = dist if enough.all() and ok.all() else np.nan_to_num(dist, nan=0.0)
        top = np.maximum(top, d0.max(axis=0))
    return top


def _check_spread(med: np.ndarray, rec, limits: Limits) -> float:
    """The face's spread from the per-frame medians (exact), checked as
    :func:`~facemotion.ingest.validation.check_face_spread` checks it."""
    enough = ~np.isnan(med)
    spread = float(np.median(med[enough])) if enough.any() else float("nan")
    return check_spread_value(spread, rec, limits)
