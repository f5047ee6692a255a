"""The displacement matrix A (Lucero & Munhall 2008) and its npz file.

Each sentence's positions minus that sentence's neutral pose are stacked frame-major:
row 3*f + c of A is axis c (x, y, z) of frame f of the concatenated sentences, column j is
marker ``labels[j]``, in mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from facemotion.errors import InputError
from facemotion.io.recording import Recording, finite_samples

if TYPE_CHECKING:
    import pandas as pd


NEUTRAL_MODES = ("first_frame", "mean_first_10")


@dataclass
class Displacements:
    A: np.ndarray            # (3F, n) mm; rows frame-major: row 3*f + c is axis c of frame f
    labels: list[str]        # n marker labels (strings)
    sentences: list[str]     # sentence (take) names in order
    row_sentence: np.ndarray  # (3F,) int, index into sentences
    row_frame: np.ndarray    # (3F,) int, frame number within its sentence
    rate: float              # Hz
    fill_mask: np.ndarray    # (F, n) bool, True where the sample was filled
    head_residual: np.ndarray  # (F,) mm, RMS residual of the head fit (0 when no head markers)
    neutral: np.ndarray      # (n, 3) mm, neutral pose (mean of the sentences' neutral poses)
    sentence_neutral: np.ndarray | None = field(default=None)  # (S, n, 3) each one's neutral

    def __post_init__(self) -> None:
        self.labels = [str(x) for x in self.labels]
        self.sentences = [str(x) for x in self.sentences]
        self.A = np.asarray(self.A, dtype=float)
        self.row_sentence = np.asarray(self.row_sentence, dtype=np.int64)
        self.row_frame = np.asarray(self.row_frame, dtype=np.int64)
        self.fill_mask = np.asarray(self.fill_mask, dtype=bool)
        self.head_residual = np.asarray(self.head_residual, dtype=float)
        self.neutral = np.asarray(self.neutral, dtype=float)
        self.rate = float(self.rate)
        rows, n = self.A.shape
        F = rows // 3
        if rows % 3 or len(self.labels) != n or self.row_sentence.shape != (rows,) \
                or self.row_frame.shape != (rows,) or self.fill_mask.shape != (F, n) \
                or self.head_residual.shape != (F,) or self.neutral.shape != (n, 3):
            raise InputError(f"displacements: inconsistent shapes: A {self.A.shape}, "
                             f"{len(self.labels)} labels, row_sentence {self.row_sentence.shape}"
                             f", row_frame {self.row_frame.shape}, fill_mask "
                             f"{self.fill_mask.shape}, head_residual {self.head_residual.shape}"
                             f", neutral {self.neutral.shape}")
        if self.sentence_neutral is not None:
            self.sentence_neutral = np.asarray(self.sentence_neutral, dtype=float)
            if self.sentence_neutral.shape != (len(self.sentences), n, 3):
                raise InputError(f"displacements: sentence_neutral shape "
                                 f"{self.sentence_neutral.shape} != "
                                 f"({len(self.sentences)}, {n}, 3)")

    @property
    def n_frames(self) -> int:
        return self.A.shape[0] // 3

    def frames(self) -> np.ndarray:
        """(F, n, 3) displacements, the inverse of the frame-major layout of A."""
        return self.A.reshape(self.n_frames, 3, -1).transpose(0, 2, 1)

    def to_frame(self):
        """A as a pandas DataFrame: one column per marker (mm), rows indexed by
        (sentence, frame, axis) in the frame-major order of A."""
        import pandas as pd

        index = pd.MultiIndex.from_arrays(
            [np.asarray(self.sentences, dtype=object)[self.row_sentence], self.row_frame,
             np.tile(np.array(["x", "y", "z"], dtype=object), self.n_frames)],
            names=["sentence", "frame", "axis"])
        return pd.DataFrame(self.A, index=index, columns=list(self.labels))

    def select_markers(self, labels) -> Displacements:
        """Only these markers (columns), in this order; an unknown label is an error."""
        labels = [str(x) for x in labels]
        missing = [m for m in labels if m not in self.labels]
        if missing:
            raise InputError(f"displacements: marker(s) {missing[:10]} not in the data")
        idx = [self.labels.index(m) for m in labels]
        sn = None if self.sentence_neutral is None else self.sentence_neutral[:, idx]
        return Displacements(self.A[:, idx], labels, self.sentences, self.row_sentence,
                             self.row_frame, self.rate, self.fill_mask[:, idx],
                             self.head_residual, self.neutral[idx], sn)

    def rows_for(self, sentence_indices) -> np.ndarray:
        """Bool mask over the rows of A of the given sentences (indices into ``sentences``)."""
        idx = self._check_indices(sentence_indices)
        return np.isin(self.row_sentence, idx)

    def subset(self, sentence_indices) -> Displacements:
        """Only these sentences, in the given order (re-indexed 0..k-1)."""
        idx = self._check_indices(sentence_indices)
        rows = np.concatenate([np.flatnonzero(self.row_sentence == s) for s in idx]
                              ) if idx else np.zeros(0, dtype=np.int64)
        frames = rows[::3] // 3
        new_sent = np.concatenate([np.full(np.sum(self.row_sentence == s), k, dtype=np.int64)
                                   for k, s in enumerate(idx)]) if idx else rows
        if self.sentence_neutral is not None and idx:
            sn = self.sentence_neutral[idx]
            neutral = sn.mean(axis=0)
        else:
            sn, neutral = None, self.neutral.copy()
        return Displacements(
            A=self.A[rows], labels=list(self.labels), sentences=[self.sentences[s] for s in idx],
            row_sentence=new_sent, row_frame=self.row_frame[rows], rate=self.rate,
            fill_mask=self.fill_mask[frames], head_residual=self.head_residual[frames],
            neutral=neutral, sentence_neutral=sn)

    def _check_indices(self, sentence_indices) -> list[int]:
        return check_sentence_indices(sentence_indices, len(self.sentences))


def _neutral_pose(rec: Recording, neutral: str) -> np.ndarray:
    if neutral == "first_frame":
        return rec.points[0].copy()
    return rec.points[:10].mean(axis=0)


def check_same_take_layout(rec: Recording, first: Recording, where: str = "",
                           first_where: str = "") -> None:
    """A take must have the first take's markers, in the same order, and its frame rate."""
    where = where or rec.source
    first_where = first_where or first.source
    if rec.labels != first.labels:
        raise InputError(f"{where}: marker labels differ from {first_where}: "
                         + label_difference(rec, first))
    if rec.rate != first.rate:
        raise InputError(f"{where}: frame rate {rec.rate} Hz differs from {first_where} "
                         f"({first.rate} Hz)")


def label_difference(rec: Recording, first: Recording) -> str:
    extra = [x for x in rec.labels if x not in set(first.labels)]
    lacking = [x for x in first.labels if x not in set(rec.labels)]
    what = []
    if extra:
        what.append(f"extra markers {', '.join(extra[:10])}")
    if lacking:
        what.append(f"missing markers {', '.join(lacking[:10])}")
    if not what:
        moved = [a for a, b in zip(rec.labels, first.labels, strict=True) if a != b]
        what.append(f"same markers in a different order (first differing: "
                    f"{', '.join(moved[:5])})")
    return "; ".join(what)


def build_displacements(recordings: list[Recording] | Recording,
                        names: list[str] | None = None, neutral: str = "first_frame",
                        head_residuals=None) -> Displacements:
    """Stack the sentences' displacements from their neutral poses into A
    (``facemotion.displacement_matrix``).

    names: one per recording; default: each recording's file name without its suffix.
    neutral: "first_frame" (each sentence's first frame) or "mean_first_10" (mean of its
    first 10 frames). head_residuals: per-sentence (frames,) arrays from
    :func:`facemotion.ingest.head_motion.align_head`, or None (zeros). All recordings must share
    labels (same order) and rate and have no NaN left (fill gaps first).
    """
    if neutral not in NEUTRAL_MODES:
        raise InputError(f"neutral: must be one of {', '.join(NEUTRAL_MODES)}, "
                         f"got {neutral!r}")
    recordings = [recordings] if isinstance(recordings, Recording) else list(recordings)
    if names is None:
        names = [Path(r.source).stem if r.source else f"take{i + 1}"
                 for i, r in enumerate(recordings)]
    names = [str(x) for x in names]
    if not recordings:
        raise InputError("displacements: no recordings given")
    if len(names) != len(recordings):
        raise InputError(f"displacements: {len(names)} names for {len(recordings)} recordings")
    if len(set(names)) != len(names):
        raise InputError(f"displacements: sentence names repeated: {names}")
    if head_residuals is None:
        head_residuals = [np.zeros(r.n_frames) for r in recordings]
    head_residuals = [np.asarray(h, dtype=float) for h in head_residuals]
    if len(head_residuals) != len(recordings):
        raise InputError(f"displacements: {len(head_residuals)} head residual arrays for "
                         f"{len(recordings)} recordings")
    first = recordings[0]
    for rec, name in zip(recordings, names, strict=True):
        check_same_take_layout(rec, first, rec.source or name, first.source or names[0])
    n = first.n_markers
    A = np.empty((3 * sum(r.n_frames for r in recordings), n))  # written once, in place
    neutrals, rs, rf = [], [], []
    r0 = 0
    for s, (rec, name, hr) in enumerate(zip(recordings, names, head_residuals, strict=True)):
        src = rec.source or name
        if rec.n_frames == 0:
            raise InputError(f"{src}: recording has no frames")
        if hr.shape != (rec.n_frames,):
            raise InputError(f"{src}: head residual has shape {hr.shape}, expected "
                             f"({rec.n_frames},)")
        bad = ~finite_samples(rec.points)
        if bad.any():
            f, j = (int(x) for x in np.argwhere(bad)[0])  # row-major: earliest frame
            raise InputError(f"{src}: marker {rec.labels[j]!r} is missing at t = "
                             f"{f / rec.rate:.3f} s (frame {f}); fill gaps first")
        n0 = _neutral_pose(rec, neutral)
        neutrals.append(n0)
        # rows (frame f, axis c) = points[f, :, c] - n0[:, c]: frame-major, x y z per frame
        F = rec.n_frames
        np.subtract(rec.points.transpose(0, 2, 1), n0.T, out=A[r0:r0 + 3 * F].reshape(F, 3, n))
        r0 += 3 * F
        rs.append(np.full(3 * F, s, dtype=np.int64))
        rf.append(np.repeat(np.arange(F, dtype=np.int64), 3))
    sn = np.stack(neutrals)
    return Displacements(
        A=A, labels=list(first.labels), sentences=names,
        row_sentence=np.concatenate(rs), row_frame=np.concatenate(rf), rate=first.rate,
        fill_mask=np.concatenate([r.filled for r in recordings]),
        head_residual=np.concatenate(head_residuals), neutral=sn.mean(axis=0),
        sentence_neutral=sn)


def split_roles(d: Displacements, sentences: pd.DataFrame | str | Path
                ) -> tuple[Displacements, Displacements | None]:
    """Training and held-out parts of a dataset, by the ``role`` column of sentences.tsv."""
    import pandas as pd  # here: reading A needs no pandas

    if not isinstance(sentences, pd.DataFrame):
        sentences = pd.read_csv(sentences, sep="\t", dtype={"sentence": str})
    role = dict(zip(sentences["sentence"], sentences["role"], strict=True))
    unknown = [s for s in d.sentences if s not in role]
    if unknown:
        raise InputError(f"sentences table does not list sentence(s) {unknown[:5]}")
    train = [i for i, s in enumerate(d.sentences) if role[s] == "train"]
    held = [i for i, s in enumerate(d.sentences) if role[s] == "heldout"]
    if not train:
        raise InputError("dataset has no training sentences")
    return d.subset(train), (d.subset(held) if held else None)


def sentence_rows(row_sentence, rows: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Sentence ids in order of first appearance and the row indices of each."""
    rs = np.asarray(row_sentence)
    if rs.shape != (rows,):
        raise InputError(
            f"row_sentence: expected {rows} entries (one per row of A), got {rs.shape}"
        )
    if rows % 3 or np.any(rs.reshape(-1, 3) != rs.reshape(-1, 3)[:, :1]):
        raise InputError("row_sentence: the 3 rows of a frame must belong to the same sentence")
    starts = np.concatenate([[0], np.flatnonzero(rs[1:] != rs[:-1]) + 1])
    run_ids = rs[starts]
    if np.unique(run_ids).size == run_ids.size:  # usual case: each sentence one run of rows
        ends = np.append(starts[1:], rows)
        return run_ids, [np.arange(a, b) for a, b in zip(starts, ends, strict=True)]
    ids, first, inverse = np.unique(rs, return_index=True, return_inverse=True)
    by_row = np.argsort(inverse, kind="stable")
    counts = np.bincount(inverse, minlength=ids.size)
    groups = np.split(by_row, np.cumsum(counts)[:-1])
    appearance = np.argsort(first, kind="stable")
    return ids[appearance], [groups[i] for i in appearance]


def check_sentence_indices(sentence_indices, n: int) -> list[int]:
    """0-based sentence indices as ints; InputError if one is out of range or repeated."""
    idx = [int(i) for i in np.atleast_1d(np.asarray(sentence_indices, dtype=np.int64))]
    bad = [i for i in idx if not 0 <= i < n]
    if bad:
        raise InputError(f"displacements: sentence index(es) {bad} out of range "
                         f"(have {n} sentences)")
    if len(set(idx)) != len(idx):
        raise InputError(f"displacements: sentence index(es) repeated in {idx}")
    return idx
