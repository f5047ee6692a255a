"""Detect markers that are copies of other markers, over the whole recording or during a gap.

Why it matters: a marker copied from another over the whole recording makes A rank deficient
and silently lowers the epsilon-rank of Lucero & Munhall (2008); a gap filled by copying a
neighbour's trajectory leaves the rank untouched but fakes perfect predictability there.

Physical principle: a copied sample carries the SAME measurement noise as its source.  Two
independently measured markers i, j with per-coordinate noise s_i, s_j have velocities (first
differences, which remove any constant offset of the copy) whose difference v_i - c v_j has a
noise floor of sqrt(2) sqrt(s_i^2 + c^2 s_j^2) per coordinate, however correlated their motion
is.  A copy (d_i = c d_j + offset, c ~ 1) has residual ~0.  We report

    residual_rms_mm = RMS(v_i - c v_j) / sqrt(2)           (per coordinate, c fitted)

which is the positional noise the difference d_i - c d_j would have if it were white: for two
independent markers it is >= sqrt(s_i^2 + c^2 s_j^2) (~ sqrt(2) x noise for c = 1), for a copy it
is ~0.  A window is flagged when

    residual_rms_mm < max_residual_fraction * min(noise_mm, noise estimate of i and of j)

(default 0.4 x noise, i.e. < 0.3 of the independent floor sqrt(2) noise: a copy made in head
coordinates keeps, after our own head alignment, a residual of the alignment's rotation error
times the distance between the two markers -- about 0.1 mm for the virtual S1's eyelids 64 mm
apart -- which a stricter threshold fragments into pieces) and the fitted
coefficient c lies in ``coefficient_range`` (a copy has c ~ 1; the range also keeps a smooth,
noise-free segment from being "explained" by c ~ 0).  The per-marker noise estimate is
RMS(second difference) / sqrt(6) (the white-noise value), the median over windows; it only
lowers the threshold (an overestimate when the motion is fast), which protects smoothed data
whose real noise is far below ``noise_mm``.  ``noise_mm`` should be the noise of the data as
given (after any smoothing).

Scan: velocities are split, within each sentence, into blocks of half ``min_duration_s``; the
Gram matrix of every block (all n x n marker pairs at once, one batched matmul) gives c and the
residual of every ordered pair in every block.  Runs of flagged blocks are refined to the frame
by the per-sample residual at their edges, kept when at least ``min_duration_s`` long, and runs
that touch across a sentence boundary are merged, so a whole-recording copy is ONE row.

Orientation: ``marker`` is the copy and ``explained_by`` its source.  With ``fill_mask``
(F x n, True where a sample was filled) the marker with more filled frames in the interval is
the copy; otherwise the marker later in column order is reported as the copy (the data alone
cannot tell which of two identical trajectories is the original).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.ingest.displacements import sentence_rows

COLUMNS = [
    "marker",
    "explained_by",
    "coefficient",
    "residual_rms_mm",
    "start_s",
    "end_s",
    "start_frame",
    "end_frame",
    "n_frames",
    "sentences",
]
_CHUNK_BYTES = 64 * 2**20  # per n x n temporary of the batched Gram (there are about five)


def _positive(name, value):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: must be a positive number, got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name}: must be a positive number, got {value!r}")
    return v


def find_redundant_markers(
    A,
    labels: Sequence[str],
    row_sentence,
    rate: float,
    noise_mm: float = 0.5,
    min_duration_s: float = 0.5,
    max_residual_fraction: float = 0.4,
    coefficient_range: tuple[float, float] = (0.5, 2.0),
    sentence_names: Sequence[str] | None = None,
    fill_mask: np.ndarray | None = None,
) -> pd.DataFrame:
    """One row per interval where a marker is a copy of another (see the module docstring).

    Columns: marker (the copy), explained_by (its source), coefficient (c in d_i ~ c d_j),
    residual_rms_mm, start_s / end_s (absolute time in the concatenated recording, half-open
    [start, end): frames start_frame .. end_frame - 1 at ``rate``), n_frames, sentences
    (comma-separated names, or sentence indices when ``sentence_names`` is None).
    """
    A = np.asarray(A, dtype=float)
    labels = [str(x) for x in labels]
    if A.ndim != 2 or A.shape[1] != len(labels) or A.shape[0] % 3:
        raise InputError(f"A: expected a (3F x {len(labels)}) matrix, got shape {A.shape}")
    crit = CopyCriteria.checked(rate, noise_mm, min_duration_s, max_residual_fraction,
                                coefficient_range)
    _check_finite(A, labels)
    F, n = A.shape[0] // 3, A.shape[1]
    ids, groups = sentence_rows(row_sentence, A.shape[0])
    sentence_names, fill_mask = _check_sentences_and_mask(sentence_names, fill_mask, ids, F, n)
    frame_groups = [g[::3] // 3 for g in groups]  # frames of each sentence, recording order
    b = max(2, int(np.ceil(crit.min_duration_s * crit.rate / 2)))  # velocity samples per block
    vel = velocity_blocks(A.reshape(F, 3, n), frame_groups, b)
    if vel is None:
        return pd.DataFrame(columns=COLUMNS)
    sigma_hat = noise_estimate(vel, crit.noise_mm)
    floor = np.minimum(crit.noise_mm, np.minimum.outer(sigma_hat, sigma_hat))
    thr = np.maximum(crit.max_residual_fraction * floor, 1e-9)  # on residual_rms_mm, per pair
    flagged = flag_blocks(vel, thr, crit.coefficient_range)
    intervals = flagged_intervals(flagged, vel, thr)
    rows = []
    for i, j, f0, f1, sents in merge_across_sentences(intervals, frame_groups):
        row = _interval_row(vel, frame_groups, labels, (i, j), (f0, f1), sents, crit, fill_mask)
        if row is not None:
            names = [sentence_names[int(ids[s])] if sentence_names is not None else str(ids[s])
                     for s in sents]
            rows.append({**row, "sentences": ",".join(names)})
    out = pd.DataFrame(rows, columns=COLUMNS)
    return out.sort_values(["start_frame", "marker", "explained_by"], ignore_index=True)


@dataclass(frozen=True)
class CopyCriteria:
    """What makes an interval a copy (module docstring): the data's noise, the shortest copy,
    the residual's fraction of the noise floor and the range of the coefficient c."""

    rate: float
    noise_mm: float = 0.5
    min_duration_s: float = 0.5
    max_residual_fraction: float = 0.4
    coefficient_range: tuple[float, float] = (0.5, 2.0)

    @classmethod
    def checked(cls, rate, noise_mm, min_duration_s, max_residual_fraction,
                coefficient_range) -> CopyCriteria:
        """The criteria from settings, each checked (one-line InputError naming it)."""
        rate = _positive("rate", rate)
        noise_mm = _positive("noise_mm", noise_mm)
        min_duration_s = _positive("min_duration_s", min_duration_s)
        frac = _positive("max_residual_fraction", max_residual_fraction)
        c_lo, c_hi = (float(x) for x in coefficient_range)
        if not 0 < c_lo < c_hi:
            raise InputError(f"coefficient_range: need 0 < low < high, got {coefficient_range!r}")
        return cls(rate, noise_mm, min_duration_s, frac, (c_lo, c_hi))


def _check_finite(A: np.ndarray, labels: list[str]) -> None:
    bad = ~np.isfinite(A).all(axis=0)
    if bad.any():
        names = ", ".join(labels[j] for j in np.flatnonzero(bad))
        raise InputError(f"A: NaN or inf displacements in marker(s) {names}")


def _check_sentences_and_mask(sentence_names, fill_mask, ids: np.ndarray, F: int, n: int):
    if sentence_names is not None:
        sentence_names = [str(s) for s in sentence_names]
        if len(sentence_names) <= int(np.max(ids)):
            raise InputError(
                f"sentence_names: {len(sentence_names)} names for sentence index {np.max(ids)}"
            )
    if fill_mask is not None:
        fill_mask = np.asarray(fill_mask, dtype=bool)
        if fill_mask.shape != (F, n):
            raise InputError(f"fill_mask: expected shape {(F, n)}, got {fill_mask.shape}")
    return sentence_names, fill_mask


@dataclass
class VelocityBlocks:
    """Velocities v(t) = d(t+1) - d(t) within each sentence, cut into blocks of ``b`` samples.

    ``per_sentence``: (frames, velocities (T, 3, n)) of each sentence; ``blocks``: (nblocks,
    3 b, n), the last block of a sentence zero-padded; ``counts``: velocity samples in each
    block; ``t0``: each block's first velocity sample in its sentence; ``sentence``: its
    sentence.
    """

    per_sentence: list[tuple[np.ndarray, np.ndarray]]
    blocks: np.ndarray
    counts: np.ndarray
    t0: np.ndarray
    sentence: np.ndarray
    b: int


def velocity_blocks(D: np.ndarray, frame_groups: list[np.ndarray], b: int
                    ) -> VelocityBlocks | None:
    """The velocities of D (F, 3, n) in blocks of ``b`` samples, sentence by sentence (None when
    no sentence has two frames)."""
    n = D.shape[2]
    V_parts, counts, block_t0, block_sent = [], [], [], []
    vel = []
    for s, fr in enumerate(frame_groups):
        if fr.size < 2:
            vel.append((fr, np.zeros((0, 3, n))))
            continue
        Vs = np.diff(D[fr], axis=0)  # v(t) = d(t+1) - d(t), within the sentence
        vel.append((fr, Vs))
        nb = int(np.ceil(Vs.shape[0] / b))
        pad = np.zeros((nb * b, 3, n))
        pad[: Vs.shape[0]] = Vs
        V_parts.append(pad.reshape(nb, 3 * b, n))
        cnt = np.full(nb, b)
        cnt[-1] = Vs.shape[0] - (nb - 1) * b
        counts.append(cnt)
        block_t0.append(np.arange(nb) * b)
        block_sent.append(np.full(nb, s))
    if not V_parts:
        return None
    return VelocityBlocks(vel, np.concatenate(V_parts), np.concatenate(counts),
                          np.concatenate(block_t0), np.concatenate(block_sent), b)


def noise_estimate(vel: VelocityBlocks, noise_mm: float) -> np.ndarray:
    """Per-marker noise (mm): RMS(second difference) / sqrt(6), the white-noise value, median
    over blocks; ``noise_mm`` for every marker when no sentence has two blocks."""
    b = vel.b
    n = vel.blocks.shape[2]
    acc = []
    for _, Vs in vel.per_sentence:
        if Vs.shape[0] >= 2 * b:
            a2 = np.diff(Vs, axis=0)
            m = (a2.shape[0] // b) * b
            acc.append(np.sqrt((a2[:m].reshape(-1, b * 3, n) ** 2).mean(axis=1)))
    return np.median(np.concatenate(acc), axis=0) / np.sqrt(6.0) if acc else np.full(n, noise_mm)


def flag_blocks(vel: VelocityBlocks, thr: np.ndarray, coefficient_range: tuple[float, float]
                ) -> np.ndarray:
    """(nblocks, n, n) bool, symmetric: blocks where marker i ~ c marker j with the residual
    below ``thr[i, j]`` and c in the range, from each block's Gram matrix (batched)."""
    c_lo, c_hi = coefficient_range
    Vb, counts = vel.blocks, vel.counts
    nblocks, n = Vb.shape[0], Vb.shape[2]
    flagged = np.zeros((nblocks, n, n), dtype=bool)
    valid = counts >= max(2, vel.b // 2)
    off = ~np.eye(n, dtype=bool)
    chunk = max(1, min(1024, _CHUNK_BYTES // (8 * n * n)))  # blocks per batched Gram
    for start in range(0, nblocks, chunk):
        Vc = Vb[start : start + chunk]
        G = np.matmul(Vc.transpose(0, 2, 1), Vc)  # (blocks, n, n): <v_i, v_j> per block
        gd = np.diagonal(G, axis1=1, axis2=2)  # <v_j, v_j>
        with np.errstate(divide="ignore", invalid="ignore"):
            c = G / gd[:, None, :]  # c[i, j]: v_i ~ c v_j
            ss = gd[:, :, None] - G * c  # residual sum of squares of v_i - c v_j
        ns = 3 * counts[start : start + chunk, None, None]
        res = np.sqrt(np.maximum(ss, 0) / ns / 2.0)  # residual_rms_mm
        ok = (res < thr) & (c > c_lo) & (c < c_hi) & (gd[:, None, :] > 0) & off
        ok &= valid[start : start + chunk, None, None]
        flagged[start : start + chunk] = ok | ok.transpose(0, 2, 1)
    return flagged


def flagged_intervals(flagged: np.ndarray, vel: VelocityBlocks, thr: np.ndarray
                      ) -> list[tuple[int, int, int, int, int]]:
    """Runs of flagged blocks of each pair i < j within a sentence, refined to the frame:
    (i, j, first frame, end frame (exclusive), sentence)."""
    n = flagged.shape[1]
    block_sent, block_t0, counts = vel.sentence, vel.t0, vel.counts
    intervals = []
    bi, ii, jj = np.nonzero(flagged & np.triu(np.ones((n, n), dtype=bool), 1)[None])
    order = np.lexsort((bi, jj, ii))
    bi, ii, jj = bi[order], ii[order], jj[order]
    brk = np.flatnonzero(
        (np.diff(bi) != 1)
        | (np.diff(ii) != 0)
        | (np.diff(jj) != 0)
        | (np.diff(block_sent[bi]) != 0)
    )
    starts = np.concatenate([[0], brk + 1]).astype(int) if bi.size else np.array([], int)
    ends = np.concatenate([brk, [bi.size - 1]]).astype(int) if bi.size else np.array([], int)
    for a, z in zip(starts, ends, strict=True):
        i, j, s = int(ii[a]), int(jj[a]), int(block_sent[bi[a]])
        fr, Vs = vel.per_sentence[s]
        t0 = int(block_t0[bi[a]])
        t1 = int(block_t0[bi[z]] + counts[bi[z]])  # velocity samples [t0, t1)
        t0, t1 = _refine(Vs[:, :, i], Vs[:, :, j], t0, t1, float(thr[i, j]))
        if t1 <= t0:
            continue
        intervals.append((i, j, int(fr[t0]), int(fr[t1]) + 1, s))  # frames fr[t0]..fr[t1]
    return intervals


def merge_across_sentences(intervals: list[tuple[int, int, int, int, int]],
                           frame_groups: list[np.ndarray]) -> list[list]:
    """Intervals of a pair that run to the end of one sentence and from the start of the next
    joined into one: [i, j, first frame, end frame, [sentences]]."""
    first_frame = {s: int(fr[0]) for s, fr in enumerate(frame_groups) if fr.size}
    last_frame = {s: int(fr[-1]) for s, fr in enumerate(frame_groups) if fr.size}
    merged: list[list] = []
    for i, j, f0, f1, s in sorted(intervals):
        if merged:
            pi, pj, pf0, pf1, ps = merged[-1]
            touching = (
                pi == i and pj == j and ps[-1] + 1 == s
                and pf1 == last_frame[ps[-1]] + 1 and f0 == first_frame[s]
            )
            if touching:
                merged[-1] = [i, j, pf0, f1, [*ps, s]]
                continue
        merged.append([i, j, f0, f1, [s]])
    return merged


def _interval_row(vel: VelocityBlocks, frame_groups: list[np.ndarray], labels: list[str],
                  pair: tuple[int, int], span: tuple[int, int], sents: list[int],
                  crit: CopyCriteria, fill_mask: np.ndarray | None) -> dict | None:
    """The copy, its source, c and the residual over the interval's velocity samples (within
    sentences only); None when the interval is shorter than ``crit.min_duration_s``."""
    (i, j), (f0, f1) = pair, span
    frames = np.concatenate(
        [frame_groups[s][(frame_groups[s] >= f0) & (frame_groups[s] < f1)] for s in sents]
    )
    if frames.size < crit.min_duration_s * crit.rate:
        return None
    vi, vj = [], []
    for s in sents:
        fr, Vs = vel.per_sentence[s]
        sel = (fr[:-1] >= f0) & (fr[1:] < f1)
        vi.append(Vs[sel, :, i])
        vj.append(Vs[sel, :, j])
    vi, vj = np.concatenate(vi), np.concatenate(vj)
    src, cpy = j, i
    fi = fj = 0
    if fill_mask is not None:
        fi, fj = fill_mask[frames, i].sum(), fill_mask[frames, j].sum()
    if fj > fi or (fj == fi and i < j):
        # the more-filled marker is the copy; with no fill flags to tell, the later column
        src, cpy, vi, vj = i, j, vj, vi
    coef = float(np.sum(vi * vj) / np.sum(vj * vj))  # least squares c in v_i ~ c v_j
    resid = float(np.sqrt(np.mean((vi - coef * vj) ** 2) / 2.0))  # residual_rms_mm
    return {"marker": labels[cpy], "explained_by": labels[src], "coefficient": coef,
            "residual_rms_mm": resid,
            "start_s": f0 / crit.rate, "end_s": f1 / crit.rate, "start_frame": f0,
            "end_frame": f1, "n_frames": int(frames.size)}


def _refine(vi, vj, t0, t1, thr):
    """Trim/extend the velocity-sample range [t0, t1) of a run of flagged blocks to the frame.

    Per sample residual (per coordinate RMS of v_i - c v_j, / sqrt(2)) with c fitted on the run;
    trim edge samples above the threshold, then extend while the neighbours are below it.
    """
    den = np.sum(vj[t0:t1] ** 2)
    c = np.sum(vi[t0:t1] * vj[t0:t1]) / den if den > 0 else 1.0
    r = np.sqrt(np.mean((vi - c * vj) ** 2, axis=1) / 2.0)
    below = r < thr
    while t0 < t1 and not below[t0]:
        t0 += 1
    while t1 > t0 and not below[t1 - 1]:
        t1 -= 1
    while t0 > 0 and below[t0 - 1]:
        t0 -= 1
    while t1 < r.size and below[t1]:
        t1 += 1
    return t0, t1


def longest(table: pd.DataFrame, n: int) -> pd.DataFrame:
    """The ``n`` longest intervals of a :func:`find_redundant_markers` table (ties: the
    smaller residual first, then the table's order): the readable top of a long table."""
    if table.empty:
        return table.copy()
    key = table.assign(_d=-(table["end_s"] - table["start_s"]), _i=range(len(table)))
    return table.loc[key.sort_values(["_d", "residual_rms_mm", "_i"]).index[:n]]
