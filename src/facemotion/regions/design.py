"""Marker-set design: which k markers to place, and how well they predict the others.

From pilot recordings (the sentences of one talker, or of several), the design answers a lab's
question "which k markers do I glue on the next speakers?":

1. **k for a target error.**  The held-out error curve of the QR procedure (Lucero & Munhall
   2008, Sec. II.C-D, Fig. 10) is estimated by cross-validation over sentences: for each fold the
   markers are ranked (with forced and excluded markers, :func:`constrained_ranking`) on the
   other sentences and the fold's sentences are predicted (:func:`sentence_error_sums`).  k is
   then :func:`facemotion.regions.target.k_for_error` of that curve: the same definition, and
   the same sentence bootstrap, as the study's summary (rank.tsv's k_for_target).
2. **The set at that k.**  Candidates of k markers: the first k pivots of the QR ranking on all
   pilot sentences, greedy forward selection (:func:`~facemotion.regions.optimality.greedy_subset`)
   and, when C(n, k) subsets can be enumerated and no marker is forced or excluded, the exhaustive
   optimum of the training residual.  Each candidate's held-out error is estimated by the same
   cross-validation with the subset fixed (X = A_m^+ A_s refitted on the training folds, the
   least-squares solution that R11^-1 R12 is for the QR subset).  The recommendation is the
   candidate with the smallest held-out error, so it is never worse than greedy selection on
   this measure; the others are reported with their gap to it.
3. **Expected error per marker, with an interval.**  Each predicted marker's mean 3-D held-out
   error and the pooled mean, with bootstrap intervals over sentences (and over subjects
   first when the sentences come from several, :func:`bootstrap_weights`): the expanded
   percentile interval (:func:`expanded_alpha`), as a pilot has few sentences.  The pooled
   mean's interval also resamples the choice of the set (:func:`selection_interval`): the
   set is chosen from the sentences that then measure it, which flatters it, so each
   resample chooses its own set again and the interval follows the resampled difference
   between that set's error and its estimate.

``symmetric`` restricts the candidates to left-right symmetric sets: markers are paired by their
labels (:func:`mirror_pairs`), and greedy selection adds a pair, or a midline marker, at a time.

The fitted set is saved as JSON (:meth:`MarkerSetDesign.save`; format in docs/design.md) and
applied to new takes by :mod:`facemotion.regions.reconstruct`.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.regions.optimality import exhaustive_subset, greedy_subset, projection_residual
from facemotion.regions.selector import _labels_in, constrained_ranking
from facemotion.regions.target import (
    DEFAULT_LEVEL,
    DEFAULT_RESAMPLES,
    DEFAULT_TARGET_MM,
    KForError,
    SentenceErrors,
    bootstrap_weights,
    k_for_error,
    sentence_error_sums,
)

#: The saved file's ``format`` and ``version`` (docs/design.md).
FILE_FORMAT = "facemotion-marker-set"
FILE_VERSION = 1
#: Cross-validation: leave one sentence out up to this many sentences, else this many folds.
MAX_FOLDS = 20
#: Exhaustive search only up to this many subsets C(n, k).
MAX_SUBSETS = 2_000_000


def sentence_folds(S: int, max_folds: int = MAX_FOLDS) -> list[np.ndarray]:
    """Sentence indices of each fold: one sentence per fold up to ``max_folds`` sentences,
    else ``max_folds`` folds of every max_folds-th sentence (interleaved, so that no fold is
    one end of the recording session)."""
    n = min(S, max_folds)
    return [np.arange(f, S, n) for f in range(n)]


def _check_pilot(disp) -> int:
    S = len(disp.sentences)
    if S < 2:
        raise InputError(f"design: {S} pilot sentence(s); at least 2 are needed, one to train "
                         "and one to measure the held-out error")
    return S


def _bar(total: int, what: str, show: bool):
    """A bar on stderr over the folds of a long step (a terminal only; else silent)."""
    from facemotion.ingest.loading import progress_bar

    return progress_bar(total, what, show, unit="fold")


def _tick(bar) -> None:
    if bar is not None:
        bar.update(1)


def cross_validated_errors(disp, force: Sequence[str] = (), exclude: Sequence[str] = (),
                           max_folds: int = MAX_FOLDS, progress: bool = False
                           ) -> SentenceErrors:
    """The QR procedure's held-out error of every k, summed per sentence, each sentence
    predicted by a ranking made without it (module notes, step 1).  k stops where a fold's
    curve stops (numerical rank) and before any excluded marker would become a main one.
    progress: a bar on stderr over the folds (on a terminal)."""
    S = _check_pilot(disp)
    rs = disp.row_sentence
    parts = []
    folds = sentence_folds(S, max_folds)
    bar = _bar(len(folds), "cross-validating k", progress)
    for fold in folds:
        test = np.isin(rs, fold)
        ranking = constrained_ranking(disp.A[~test], disp.labels, force=force, exclude=exclude)
        parts.append(sentence_error_sums(ranking, disp.A[test], disp.labels, rs[test],
                                         disp.sentences,
                                         k_max=len(disp.labels) - len(exclude) or None))
        _tick(bar)
    if bar is not None:
        bar.close()
    K = min(p.ks.size for p in parts)
    order = {name: i for i, name in enumerate(disp.sentences)}
    sums = np.zeros((S, K))
    counts = np.zeros((S, K))
    for p in parts:
        rows = [order[name] for name in p.sentences]
        sums[rows] = p.sums[:, :K]
        counts[rows] = p.counts[:, :K]
    return SentenceErrors(parts[0].ks[:K], sums, counts, list(disp.sentences), len(disp.labels))


def subset_errors(disp, subset: Sequence[int], max_folds: int = MAX_FOLDS, bar=None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Cross-validated held-out error of a fixed subset of main markers (column indices):
    ``sums`` (S, n), each marker's summed 3-D error distance over each sentence's frames (0 for
    the main markers, which are measured), and ``frames`` (S,).  bar: a progress bar ticked
    once a fold."""
    S = _check_pilot(disp)
    A, rs = disp.A, disp.row_sentence
    n = A.shape[1]
    main = list(subset)
    rest = [j for j in range(n) if j not in set(main)]
    sums = np.zeros((S, n))
    frames = np.bincount(rs[::3], minlength=S).astype(float)
    for fold in sentence_folds(S, max_folds):
        test = np.isin(rs, fold)
        # A_s ~= A_m X: X by least squares on the training sentences (Sec. II.D)
        X = np.linalg.lstsq(A[~test][:, main], A[~test][:, rest], rcond=None)[0]
        E = A[test][:, rest] - A[test][:, main] @ X
        F = E.shape[0] // 3
        dist = np.sqrt((E.reshape(F, 3, len(rest)) ** 2).sum(axis=1))  # (F, n - k)
        fs = rs[test][::3]
        for j, col in enumerate(rest):
            sums[:, col] += np.bincount(fs, weights=dist[:, j], minlength=S)
        _tick(bar)
    return sums, frames


_SIDES = [(r"^L(?=[A-Z_\-.0-9])", "R"), (r"^R(?=[A-Z_\-.0-9])", "L"),
          (r"^l(?=[A-Z_\-.0-9])", "r"), (r"^r(?=[A-Z_\-.0-9])", "l"),
          (r"(?<=[_\-.])L$", "R"), (r"(?<=[_\-.])R$", "L"),
          (r"(?<=[_\-.])l$", "r"), (r"(?<=[_\-.])r$", "l"),
          (r"Left", "Right"), (r"Right", "Left"), (r"left", "right"), (r"right", "left")]


def mirror_pairs(labels: Sequence[str]) -> list[tuple[str, ...]]:
    """Group labels into left-right units: a pair (a, b) when b is a's label with its side
    swapped (prefix L/R or l/r before a capital, digit or separator; suffix _L/_R, -l/-r, ...;
    Left/Right anywhere), else a single (midline) marker.  Units in the labels' order."""
    labels = [str(x) for x in labels]
    present = set(labels)
    seen: set[str] = set()
    units: list[tuple[str, ...]] = []
    for lab in labels:
        if lab in seen:
            continue
        mate = None
        for pattern, other in _SIDES:
            swapped = re.sub(pattern, other, lab, count=1)
            if swapped != lab and swapped in present and swapped not in seen:
                mate = swapped
                break
        units.append((lab, mate) if mate else (lab,))
        seen.update(units[-1])
    return units


def symmetric_greedy(G: np.ndarray, labels: Sequence[str], k: int, force: Sequence[str] = (),
                     exclude: Sequence[str] = ()) -> list[int]:
    """Greedy forward selection over left-right units (:func:`mirror_pairs`): each step adds
    the unit with the largest drop in residual; forced units first; units with an excluded
    marker never.  Stops once at least k markers are chosen (k + 1 when a pair crosses k)."""
    pos = {m: j for j, m in enumerate(labels)}
    units = [u for u in mirror_pairs(labels) if not set(u) & set(exclude)]
    forced = [u for u in units if set(u) & set(force)]
    chosen: list[int] = []
    while len(chosen) < k:
        pool = forced or units
        best, best_res = None, np.inf
        for u in pool:
            trial = chosen + [pos[m] for m in u]
            res = _gram_residual(G, trial)
            if res < best_res:
                best, best_res = u, res
        if best is None:
            raise InputError(f"symmetric: only {len(chosen)} markers can be chosen, not {k}")
        chosen += [pos[m] for m in best]
        units.remove(best)
        if best in forced:
            forced.remove(best)
    return chosen


def _gram_residual(G: np.ndarray, subset: Sequence[int]) -> float:
    """||A - P_S A||_F^2 from G = A^T A: tr(G) - tr(G_SS^+ (G^2)_SS)."""
    S = list(subset)
    GS = G[:, S]
    return float(np.trace(G) - np.trace(np.linalg.pinv(G[np.ix_(S, S)]) @ (GS.T @ GS)))


@dataclass
class MarkerSetDesign:
    """A recommended marker set (:func:`design_markers`).

    ``selected``: the k markers to place, in selection order; ``labels``: every analysed marker
    (the predicted ones are those not selected); ``coef``: X (k x n - k, main x secondary
    markers) fitted on all pilot sentences; ``per_marker``: one row per marker (role, order,
    expected held-out error and interval, mm); ``candidates``: each candidate set with its
    held-out and training errors; ``k_for_target``: k*(target) with its interval (None when k
    was given); ``neutral``: (n, 3) rest positions in the head frame of ``head_reference``
    (the head markers' positions in the same frame); ``settings``: how it was made."""

    k: int
    selected: list[str]
    labels: list[str]
    coef: pd.DataFrame
    expected_error_mm: float
    error_low_mm: float
    error_high_mm: float
    level: float
    per_marker: pd.DataFrame
    candidates: pd.DataFrame
    k_for_target: KForError | None
    sentences: list[str]
    subjects: list[str] | None = None
    head_markers: list[str] = field(default_factory=list)
    head_reference: np.ndarray | None = None
    neutral: np.ndarray | None = None
    rate: float | None = None
    settings: dict = field(default_factory=dict)

    @property
    def predicted(self) -> list[str]:
        return [m for m in self.labels if m not in set(self.selected)]

    def describe(self) -> str:
        """Lines a person reads: the set, its k and interval, the gap to the other candidates."""
        pct = f"{self.level:.0%}"
        lines = [f"markers to place (k = {self.k}): {', '.join(self.selected)}"]
        if self.head_markers:
            lines.append(f"head markers (placed too, for the head motion): "
                         f"{', '.join(self.head_markers)}")
        if self.k_for_target is not None:
            lines.append(f"k for the target: {self.k_for_target.describe()}")
        lines.append(f"expected mean held-out error of the {len(self.predicted)} predicted "
                     f"markers: {self.expected_error_mm:.3f} mm ({pct} interval "
                     f"{self.error_low_mm:.3f}-{self.error_high_mm:.3f} mm, "
                     f"{self.settings.get('resampled', 'sentences')} resampled)")
        for row in self.candidates.itertuples():
            lines.append(f"  {row.method}: held-out {row.heldout_error_mm:.3f} mm "
                         f"(+{row.gap_mm:.3f} mm), training RMS {row.training_rms_mm:.3f} mm: "
                         f"{row.subset}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The saved file's content (docs/design.md); NaN (e.g. the error at k when no k
        reaches the target) is null."""
        def arr(a):
            return None if a is None else np.round(np.asarray(a, float), 9).tolist()
        return _json_safe({
            "format": FILE_FORMAT, "version": FILE_VERSION, "k": self.k,
            "selected": self.selected, "predicted": self.predicted, "labels": self.labels,
            "coefficients": {"rows": list(self.coef.index), "columns": list(self.coef.columns),
                             "values": arr(self.coef.to_numpy())},
            "expected_error_mm": self.expected_error_mm, "error_low_mm": self.error_low_mm,
            "error_high_mm": self.error_high_mm, "level": self.level,
            "k_for_target": None if self.k_for_target is None else self.k_for_target.as_dict(),
            "per_marker": json.loads(self.per_marker.to_json(orient="records")),
            "candidates": json.loads(self.candidates.to_json(orient="records")),
            "sentences": self.sentences, "subjects": self.subjects,
            "head_markers": self.head_markers, "head_reference_mm": arr(self.head_reference),
            "neutral_mm": arr(self.neutral), "rate_hz": self.rate, "settings": self.settings,
        })

    def save(self, path) -> None:
        """Write the set as JSON (docs/design.md), whole or not at all."""
        from facemotion.io.atomic import atomic_path

        text = json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n"
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")

    @classmethod
    def load(cls, path) -> MarkerSetDesign:
        """Read a set saved by :meth:`save`; errors name the file and the field."""
        from pathlib import Path

        p = Path(path)
        if not p.is_file():
            from facemotion.errors import MissingFileError

            raise MissingFileError(f"{p}: no such marker-set file")
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise InputError(f"{p}: not a marker-set file (not JSON: {e.__class__.__name__})"
                             ) from None
        if not isinstance(d, dict) or d.get("format") != FILE_FORMAT:
            raise InputError(f"{p}: not a marker-set file (format is not {FILE_FORMAT!r})")
        if d.get("version") != FILE_VERSION:
            raise InputError(f"{p}: marker-set file version {d.get('version')!r}; this "
                             f"facemotion reads version {FILE_VERSION}")
        try:
            c = d["coefficients"]
            coef = pd.DataFrame(np.asarray(c["values"], float), index=c["rows"],
                                columns=c["columns"])
            kft = d["k_for_target"]
            return cls(
                k=int(d["k"]), selected=list(d["selected"]), labels=list(d["labels"]),
                coef=coef, expected_error_mm=float(d["expected_error_mm"]),
                error_low_mm=float(d["error_low_mm"]), error_high_mm=float(d["error_high_mm"]),
                level=float(d["level"]), per_marker=pd.DataFrame(d["per_marker"]),
                candidates=pd.DataFrame(d["candidates"]),
                k_for_target=None if kft is None else KForError(**{
                    **kft, "error_at_k_mm": float("nan") if kft["error_at_k_mm"] is None
                    else kft["error_at_k_mm"]}),
                sentences=list(d["sentences"]), subjects=d["subjects"],
                head_markers=list(d["head_markers"]),
                head_reference=None if d["head_reference_mm"] is None
                else np.asarray(d["head_reference_mm"], float),
                neutral=None if d["neutral_mm"] is None else np.asarray(d["neutral_mm"], float),
                rate=d["rate_hz"], settings=d["settings"])
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"{p}: marker-set file lacks or garbles a field ({e})") from None


def _json_safe(value):
    """NaN and infinities as None, recursively (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


#: The candidate methods (module notes, step 2).
QR, GREEDY, EXHAUSTIVE, SYMMETRIC = ("QR pivots", "greedy", "exhaustive (training residual)",
                                     "symmetric greedy")


def _methods(n: int, k: int, force, exclude, symmetric: bool, max_subsets: int) -> list[str]:
    if symmetric:
        return [SYMMETRIC]
    out = [QR, GREEDY]
    if not force and not exclude and math.comb(n, k) <= max_subsets:
        out.append(EXHAUSTIVE)
    return out


def select_subset(method: str, A: np.ndarray, labels: Sequence[str], k: int, force=(),
                  exclude=()) -> list[int]:
    """The k markers (column indices) that candidate ``method`` chooses from the rows A."""
    labels = list(labels)
    if method == QR:
        ranking = constrained_ranking(A, labels, force=force, exclude=exclude)
        return [int(j) for j in ranking.order[:k]]
    return _select_on_gram(method, A.T @ A, labels, k, force, exclude)


def _candidates(disp, k: int, force, exclude, symmetric: bool, max_subsets: int
                ) -> list[tuple[str, list[int]]]:
    """The candidate sets of k markers (module notes, step 2), as column indices."""
    return [(m, select_subset(m, disp.A, disp.labels, k, force, exclude))
            for m in _methods(len(disp.labels), k, force, exclude, symmetric, max_subsets)]


def expanded_alpha(level: float, units: int) -> float:
    """The tail probability of the expanded percentile interval (Hesterberg 2015, "What
    teachers should know about the bootstrap", Am. Stat. 69:371, Sec. 4.2): the percentile
    interval at Phi(-sqrt(n / (n - 1)) t_{n-1, 1 - alpha/2}) instead of alpha/2, which
    corrects the plain percentile interval's narrowness with few resampled units n."""
    import scipy.stats

    alpha = (1.0 - level) / 2.0
    if units < 2:
        return alpha
    z = math.sqrt(units / (units - 1)) * scipy.stats.t.ppf(1.0 - alpha, units - 1)
    return float(scipy.stats.norm.cdf(-z))


def _interval(values: np.ndarray, level: float, units: int) -> tuple[np.ndarray, np.ndarray]:
    alpha = expanded_alpha(level, units)
    return (np.quantile(values, alpha, axis=0, method="lower"),
            np.quantile(values, 1.0 - alpha, axis=0, method="higher"))


def _choose_k(disp, target_mm, k, force, exclude, groups, resamples, level, seed,
              on_unreached: str = "raise", progress: bool = False
              ) -> tuple[int, KForError | None]:
    n = len(disp.labels)
    if k is not None:
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 1 <= k < n:
            raise InputError(f"k: must be an integer in 1..{n - 1} ({n} markers), got {k!r}")
        return int(k), None
    curve = cross_validated_errors(disp, force, exclude, progress=progress)
    kft = k_for_error(curve, target_mm, resamples=resamples, level=level, seed=seed,
                      groups=groups)
    if kft.k is None and on_unreached == "largest":
        return max(kft.k_last, len(force)), kft
    if kft.k is None:
        raise InputError(f"target error: {kft.describe()} of held-out error in the pilot "
                         "sentences; give a larger target or a number of markers (k)")
    return max(kft.k, len(force)), kft


def design_markers(disp, *, target_mm: float = DEFAULT_TARGET_MM, k: int | None = None,
                   force: Sequence[str] = (), exclude: Sequence[str] = (),
                   symmetric: bool = False, groups: Sequence[str] | None = None,
                   resamples: int = DEFAULT_RESAMPLES, level: float = DEFAULT_LEVEL,
                   seed: int = 0, max_subsets: int = MAX_SUBSETS,
                   on_unreached: str = "raise", progress: bool = False,
                   selection_resamples: int | None = None) -> MarkerSetDesign:
    """Recommend k markers to place from the pilot ``Displacements`` (module notes).

    target_mm: the mean held-out error to reach (ignored when ``k`` is given); force / exclude:
    markers that must / must not be placed; symmetric: left-right symmetric sets only; groups:
    each sentence's subject (pilot sentences from several subjects), for a bootstrap over
    subjects and sentences.  resamples, level, seed: the bootstrap's.  selection_resamples:
    how many of those resamples choose the set again for the pooled interval (each runs the
    recommended selection, an exhaustive search among them; default: all).  on_unreached: when
    no k reaches the target, "raise" (InputError) or "largest" (the largest k evaluated,
    ``settings['target_reached']`` False).  progress: bars on stderr over the
    cross-validation folds (on a terminal; silent otherwise)."""
    if on_unreached not in ("raise", "largest"):
        raise InputError(f"on_unreached: 'raise' or 'largest', got {on_unreached!r}")
    labels = list(disp.labels)
    force = _labels_in("force", force, labels)
    exclude = _labels_in("exclude", exclude, labels)
    S = _check_pilot(disp)
    if groups is not None:
        groups = [str(g) for g in groups]
        if len(groups) != S:
            raise InputError(f"groups: {len(groups)} subjects given for {S} sentences")
    k, kft = _choose_k(disp, target_mm, k, force, exclude, groups, resamples, level, seed,
                       on_unreached, progress)
    if len(force) > k:
        raise InputError(f"force: {len(force)} forced markers do not fit in k = {k}")
    rows, n = disp.A.shape
    table, errs = [], {}
    candidates = _candidates(disp, k, force, exclude, symmetric, max_subsets)
    bar = _bar(len(candidates) * len(sentence_folds(S)), "scoring candidate sets", progress)
    for method, subset in candidates:
        sums, frames = subset_errors(disp, subset, bar=bar)
        errs[method] = (subset, sums, frames)
        kk = len(subset)
        table.append({"method": method, "k": kk, "subset": ",".join(labels[j] for j in subset),
                      "heldout_error_mm": float(sums.sum() / (frames.sum() * (n - kk))),
                      "training_rms_mm": projection_residual(disp.A, subset)
                      / math.sqrt(rows * (n - kk))})
    if bar is not None:
        bar.close()
    cand = pd.DataFrame(table)
    best = int(np.argmin(cand["heldout_error_mm"].to_numpy()))  # first on ties: QR
    cand["gap_mm"] = cand["heldout_error_mm"] - cand["heldout_error_mm"].iloc[best]
    cand["recommended"] = np.arange(len(cand)) == best
    method = cand["method"].iloc[best]
    subset, sums, frames = errs[method]
    W = bootstrap_weights(S, resamples, np.random.default_rng(seed), groups)
    per, overall = _per_marker(labels, subset, sums, frames, W, level, groups)
    n_sel = resamples if selection_resamples is None else int(selection_resamples)
    if not 1 <= n_sel <= resamples:
        raise InputError(f"selection_resamples: 1 to resamples ({resamples}), got {n_sel}")
    bar = _bar(n_sel, "resampling the selection", progress)
    units = S if groups is None else len(set(groups))
    overall = (overall[0], *selection_interval(disp, method, k, force, exclude, W[:n_sel],
                                               level, overall[0], units, bar))
    if bar is not None:
        bar.close()
    main = [labels[j] for j in subset]
    rest = [m for m in labels if m not in set(main)]
    X = np.linalg.lstsq(disp.A[:, subset], disp.A[:, [labels.index(m) for m in rest]],
                        rcond=None)[0]
    settings = {"target_mm": None if kft is None else float(target_mm), "force": force,
                "exclude": exclude, "symmetric": bool(symmetric), "resamples": int(resamples),
                "selection_resamples": n_sel, "seed": int(seed), "folds": len(sentence_folds(S)),
                "resampled": "subjects and sentences" if groups else "sentences",
                "target_reached": None if kft is None else kft.k is not None}
    return MarkerSetDesign(
        k=len(subset), selected=main, labels=labels, coef=pd.DataFrame(X, main, rest),
        expected_error_mm=overall[0], error_low_mm=overall[1], error_high_mm=overall[2],
        level=float(level), per_marker=per, candidates=cand, k_for_target=kft,
        sentences=list(disp.sentences),
        subjects=None if groups is None else sorted(set(groups)),
        rate=float(disp.rate), settings=settings)


def _per_marker(labels, subset, sums, frames, W, level, groups=None
                ) -> tuple[pd.DataFrame, tuple]:
    """Each marker's expected held-out error (mean 3-D distance, mm) with its bootstrap
    interval (expanded percentile over the resampled units: sentences, or subjects with
    ``groups``), and the same for the pooled mean over the predicted markers."""
    n, k = len(labels), len(subset)
    mean = sums.sum(axis=0) / frames.sum()
    boot = (W @ sums) / (W @ frames)[:, None]   # (resamples, n)
    units = W.shape[1] if groups is None else len(set(groups))
    lo, hi = _interval(boot, level, units)
    pooled = (W @ sums.sum(axis=1)) / ((W @ frames) * (n - k))
    plo, phi = _interval(pooled, level, units)
    order = {j: i + 1 for i, j in enumerate(subset)}
    per = pd.DataFrame({
        "marker": labels,
        "role": ["placed" if j in order else "predicted" for j in range(n)],
        "order": [order.get(j, 0) for j in range(n)],
        "expected_error_mm": mean, "error_low_mm": lo, "error_high_mm": hi})
    overall = float(sums.sum() / (frames.sum() * (n - k)))
    return per, (overall, float(plo), float(phi))


def _sentence_grams(disp) -> np.ndarray:
    """A_s^T A_s of every sentence s, (S, n, n)."""
    S, n = len(disp.sentences), disp.A.shape[1]
    out = np.zeros((S, n, n))
    for s in range(S):
        As = disp.A[disp.row_sentence == s]
        out[s] = As.T @ As
    return out


def _gram_factor(G: np.ndarray) -> np.ndarray:
    """B with B^T B = G: QR with column pivoting of B chooses A's pivots.  Rows padded with
    zeros to a multiple of 3, as the rows of a displacement matrix come (they add nothing to
    B^T B)."""
    lam, V = np.linalg.eigh(G)
    B = np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T
    return np.vstack([B, np.zeros((-B.shape[0] % 3, B.shape[1]))])


def _distance_sums(rows_of, sentences, main, rest, X) -> np.ndarray:
    """Summed 3-D distance between measured and predicted (A_m X) secondary markers over the
    frames of each of ``sentences`` (one product for all of them)."""
    sentences = list(sentences)
    if not sentences:
        return np.zeros(0)
    A = np.vstack([rows_of[s] for s in sentences])
    E = A[:, rest] - A[:, main] @ X
    d = np.sqrt((E.reshape(-1, 3, len(rest)) ** 2).sum(axis=1)).sum(axis=1)  # per frame
    starts = np.cumsum([0] + [rows_of[s].shape[0] // 3 for s in sentences[:-1]])
    return np.add.reduceat(d, starts)


def selection_interval(disp, method: str, k: int, force, exclude, W: np.ndarray,
                       level: float, estimate: float, units: int, bar=None
                       ) -> tuple[float, float]:
    """The interval of the pooled expected error with the choice of the set resampled too
    (module notes, step 3).  The set is chosen from the same pilot sentences that then
    measure it, which flatters it.  In each bootstrap resample (sentence weights ``W``) the
    set is chosen again by ``method`` and every pilot sentence predicted as in the
    cross-validation (X fitted on the resample without the sentence's fold; a sentence the
    resample left out by the whole resample): e_b, the pooled error weighted as the resample
    draws the sentences, is the pilot's estimate in the bootstrap world, t_b, every sentence
    once, the error on its population.  t_b - e_b stands for the unknown t - e, and the
    interval is ``estimate`` plus its expanded percentiles (:func:`expanded_alpha`, ``units``
    resampled: sentences, or subjects)."""
    labels, n = list(disp.labels), disp.A.shape[1]
    G = _sentence_grams(disp)
    rows_of = [disp.A[disp.row_sentence == s] for s in range(len(disp.sentences))]
    frames = np.array([r.shape[0] // 3 for r in rows_of], float)
    diffs = []
    for w in W:
        _tick(bar)
        inbag, oob = np.flatnonzero(w > 0), np.flatnonzero(w == 0)
        if inbag.size < 2:
            continue
        Gw = np.tensordot(w, G, axes=1)
        main = (select_subset(method, _gram_factor(Gw), labels, k, force, exclude)
                if method == QR else _select_on_gram(method, Gw, labels, k, force, exclude))
        rest = [j for j in range(n) if j not in set(main)]
        sums = np.zeros(len(frames))
        for part in [*(inbag[f] for f in sentence_folds(inbag.size)), oob]:
            Gf = Gw - np.tensordot(w[part], G[part], axes=1)
            X = np.linalg.lstsq(Gf[np.ix_(main, main)], Gf[np.ix_(main, rest)], rcond=None)[0]
            sums[part] = _distance_sums(rows_of, part, main, rest, X)
        e_b = (w @ sums) / ((w @ frames) * len(rest))
        t_b = sums.sum() / (frames.sum() * len(rest))
        diffs.append(t_b - e_b)
    if not diffs:
        return float("nan"), float("nan")
    lo, hi = _interval(np.asarray(diffs), level, units)
    return float(estimate + lo), float(estimate + hi)


def _select_on_gram(method, G, labels, k, force, exclude) -> list[int]:
    """:func:`select_subset` for the methods that need only A^T A."""
    if method == SYMMETRIC:
        return symmetric_greedy(G, labels, k, force, exclude)
    if method == GREEDY:
        return greedy_subset(G, k, force=[labels.index(m) for m in force],
                             exclude=[labels.index(m) for m in exclude])
    return exhaustive_subset(G, k)[0]
