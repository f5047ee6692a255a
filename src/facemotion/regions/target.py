"""How many main markers reach a target held-out error: k for a target, with an interval.

Beyond the papers: Lucero & Munhall plot the held-out error against k (Fig. 10) but a lab asks
the inverse question, "how many markers predict the rest within 1 mm?".  One definition serves
the study's summary (``rank.tsv``) and the marker-set design:

    k*(target) = min { k : mean_abs_error(k) <= target }

where mean_abs_error(k) is Fig. 10's measure (``prediction.error_curve``): the mean 3-D distance
between measured and predicted secondary markers over the held-out frames, pooled over the
held-out sentences.  k = n always qualifies (every marker measured, zero error).

The interval comes from resampling held-out sentences (a percentile bootstrap): sentences are
drawn with replacement, the pooled error curve recomputed from per-sentence sums, and k* taken
on each resample.  Sentences, not frames, are resampled because frames within a sentence are
strongly correlated.  The interval describes the held-out part's sampling variability for the
ranking trained here; it does not resample the training sentences.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from facemotion.errors import InputError
from facemotion.ranking.result import MarkerRanking
from facemotion.regions.prediction import _sq_dist, residual_steps

#: The default target of the summary and of ``design``: 1 mm mean 3-D held-out error.
DEFAULT_TARGET_MM = 1.0
#: Bootstrap resamples and the interval's coverage.
DEFAULT_RESAMPLES = 1000
DEFAULT_LEVEL = 0.95
#: Fewer held-out sentences than this give no interval: a bootstrap over 1-4 sentences can only
#: return a handful of distinct resamples.
MIN_SENTENCES = 5


@dataclass(frozen=True)
class SentenceErrors:
    """Per held-out sentence s and k: ``sums[s, i]`` the summed 3-D error distance over the
    sentence's frames and the secondary markers at k = ``ks[i]``, ``counts[s, i]`` the number of
    (frame, secondary marker) pairs summed.  ``n`` markers in all."""

    ks: np.ndarray
    sums: np.ndarray
    counts: np.ndarray
    sentences: list[str]
    n: int

    def pooled_mean(self, rows=None) -> np.ndarray:
        """Fig. 10's mean absolute error per k, pooled over the sentences ``rows`` (all by
        default; repeats allowed, as a bootstrap draws them)."""
        s = self.sums if rows is None else self.sums[rows]
        c = self.counts if rows is None else self.counts[rows]
        return s.sum(axis=-2) / c.sum(axis=-2)

    def weighted_mean(self, weights: np.ndarray) -> np.ndarray:
        """The pooled mean per k for sentence multiplicities ``weights`` (..., S), as
        :func:`bootstrap_weights` draws them: (..., K)."""
        return (weights @ self.sums) / (weights @ self.counts)


def bootstrap_weights(S: int, resamples: int, rng: np.random.Generator,
                      groups=None) -> np.ndarray:
    """How often each of S sentences is drawn in each of ``resamples`` bootstrap resamples,
    (resamples, S).  Without ``groups``, S sentences are drawn with replacement.  With
    ``groups`` (S,) (each sentence's subject), a two-stage bootstrap: the subjects are drawn
    with replacement, then each drawn subject's sentences with replacement among its own, so
    that the interval covers the variation between subjects as well as between sentences."""
    W = np.zeros((resamples, S))
    rows = np.arange(resamples)[:, None]
    if groups is None:
        np.add.at(W, (rows, rng.integers(0, S, size=(resamples, S))), 1.0)
        return W
    g = np.asarray(groups)
    if g.shape != (S,):
        raise InputError(f"groups: expected one subject per sentence ({S}), got {g.shape}")
    members = [np.flatnonzero(g == u) for u in np.unique(g)]
    picks = rng.integers(0, len(members), size=(resamples, len(members)))
    for i, m in enumerate(members):
        # every drawn copy of subject i contributes len(m) sentences drawn among its own
        copies = (picks == i).sum(axis=1)
        for c in np.unique(copies[copies > 0]):
            sel = np.flatnonzero(copies == c)
            draws = m[rng.integers(0, m.size, size=(sel.size, int(c) * m.size))]
            np.add.at(W, (sel[:, None], draws), 1.0)
    return W


def sentence_error_sums(train_ranking: MarkerRanking, B, labels: Sequence[str],
                        row_sentence, sentence_names: Sequence[str] | None = None,
                        k_max: int | None = None) -> SentenceErrors:
    """The held-out error of every k, summed per sentence (the same residuals as
    ``error_curve``, whose mean_abs_error_mm is ``pooled_mean()``).  ``row_sentence`` (3F,)
    gives each row of B its sentence index."""
    rs = np.asarray(row_sentence)
    rows = np.shape(B)[0]
    if rs.shape != (rows,):
        raise InputError(f"row_sentence: expected {rows} entries (one per row of B), "
                         f"got {rs.shape}")
    frame_sentence = rs[::3]
    ids, frame_index = np.unique(frame_sentence, return_inverse=True)
    frames = np.bincount(frame_index, minlength=ids.size)
    ks, sums, counts = [], [], []
    for k, Es, _ in residual_steps(train_ranking, B, labels, k_max):
        dist = np.sqrt(_sq_dist(Es)).sum(axis=0)  # (F,) summed over the secondary markers
        ks.append(k)
        sums.append(np.bincount(frame_index, weights=dist, minlength=ids.size))
        counts.append(frames * (train_ranking.n - k))
    names = [str(sentence_names[i]) if sentence_names is not None else str(i) for i in ids]
    return SentenceErrors(np.asarray(ks, dtype=int), np.asarray(sums, dtype=float).T,
                          np.asarray(counts, dtype=float).T, names, train_ranking.n)


@dataclass(frozen=True)
class KForError:
    """k*(target) with a bootstrap interval.  ``k`` is None when no k up to the curve's end
    (``k_max`` or the numerical rank, ``k_last``) reaches the target.  ``k_low`` and ``k_high``
    are both None when there is no interval (fewer than MIN_SENTENCES held-out sentences);
    ``k_high`` alone is None when more than the interval's share of resamples never reach the
    target within the curve (censored: "k_low or more")."""

    target_mm: float
    k: int | None
    k_low: int | None
    k_high: int | None
    error_at_k_mm: float
    level: float
    resamples: int
    seed: int
    heldout_sentences: int
    k_last: int

    def as_dict(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        """One line: 'k = 4 (95 % interval 3-5) for 1 mm'."""
        if self.k is None:
            return (f"no k up to {self.k_last} reaches {self.target_mm:g} mm")
        if self.k_low is None:
            return (f"k = {self.k} for {self.target_mm:g} mm mean held-out error (no interval: "
                    f"{self.heldout_sentences} held-out sentence(s), fewer than {MIN_SENTENCES})")
        hi = "more" if self.k_high is None else str(self.k_high)
        span = str(self.k) if self.k_low == self.k_high else f"{self.k_low}-{hi}"
        return (f"k = {self.k} ({self.level:.0%} interval {span}) for {self.target_mm:g} mm "
                f"mean held-out error")


def _first_k(mean: np.ndarray, ks: np.ndarray, target: float) -> np.ndarray:
    """The first k with mean <= target along the last axis; 0 where none does."""
    ok = mean <= target
    hit = ok.any(axis=-1)
    return np.where(hit, ks[np.argmax(ok, axis=-1)], 0)


def k_for_error(errors: SentenceErrors, target_mm: float = DEFAULT_TARGET_MM,
                resamples: int = DEFAULT_RESAMPLES, level: float = DEFAULT_LEVEL,
                seed: int = 0, groups=None) -> KForError:
    """k*(target) (module notes) and its percentile-bootstrap interval over held-out
    sentences.  k = n (zero error) is not among ``errors.ks``: when the curve ends before the
    target, k is None (not reached within the curve).  ``groups``: each held-out sentence's
    subject, for a two-stage bootstrap over subjects and sentences (:func:`bootstrap_weights`);
    default: sentences only."""
    if not (np.isfinite(target_mm) and target_mm > 0):
        raise InputError(f"target error: must be a positive number of mm, got {target_mm!r}")
    if not 0 < level < 1:
        raise InputError(f"interval level: must lie strictly between 0 and 1, got {level!r}")
    if isinstance(resamples, bool) or not isinstance(resamples, int) or resamples < 1:
        raise InputError(f"resamples: must be a positive integer, got {resamples!r}")
    S = errors.sums.shape[0]
    if S == 0 or errors.ks.size == 0:
        raise InputError("k for a target error: no held-out sentences or no k to evaluate")
    curve = errors.pooled_mean()
    k = int(_first_k(curve, errors.ks, target_mm))
    if groups is None:
        draws = np.random.default_rng(seed).integers(0, S, size=(resamples, S))
        kb = _first_k(errors.pooled_mean(draws), errors.ks, target_mm)
    else:
        W = bootstrap_weights(S, resamples, np.random.default_rng(seed), groups)
        kb = _first_k(errors.weighted_mean(W), errors.ks, target_mm)
    # a resample that never reaches the target within the curve sorts above every k
    kb = np.where(kb == 0, np.iinfo(np.int64).max, kb)
    alpha = (1.0 - level) / 2.0
    kb = np.sort(kb)   # the percentiles as order statistics (numpy's "lower" / "higher")
    lo = int(kb[int(np.floor(alpha * (resamples - 1)))])
    hi = int(kb[int(np.ceil((1.0 - alpha) * (resamples - 1)))])
    never = np.iinfo(np.int64).max
    if S < MIN_SENTENCES:
        k_low = k_high = None
    else:
        k_low = None if lo == never else lo
        k_high = None if hi == never else hi
    return KForError(
        target_mm=float(target_mm), k=k or None, k_low=k_low, k_high=k_high,
        error_at_k_mm=float(curve[errors.ks == k][0]) if k else float("nan"),
        level=float(level), resamples=int(resamples), seed=int(seed), heldout_sentences=S,
        k_last=int(errors.ks[-1]))


#: ``tolerance_from`` of the epsilon-rank at the data's own noise level (rank.tsv).
NOISE_LEVEL = "noise_level"


def headline_facts(train_ranking: MarkerRanking, held, *, target_mm: float = DEFAULT_TARGET_MM,
                   resamples: int = DEFAULT_RESAMPLES, level: float = DEFAULT_LEVEL,
                   seed: int = 0, k_max: int | None = None) -> dict:
    """The columns rank.tsv adds for a lab: k*(target) with its interval (``k_for_error`` on
    the held-out ``Displacements`` ``held``; empty without held-out sentences)."""
    out = {"target_error_mm": float(target_mm), "k_for_target": None, "k_for_target_low": None,
           "k_for_target_high": None, "error_at_k_mm": float("nan"),
           "interval_level": float(level), "heldout_sentences": 0}
    if held is None:
        return out
    errs = sentence_error_sums(train_ranking, held.A, held.labels, held.row_sentence,
                               held.sentences, k_max=k_max)
    kt = k_for_error(errs, target_mm, resamples=resamples, level=level, seed=seed)
    out.update(k_for_target=kt.k, k_for_target_low=kt.k_low, k_for_target_high=kt.k_high,
               error_at_k_mm=kt.error_at_k_mm, heldout_sentences=kt.heldout_sentences)
    return out
