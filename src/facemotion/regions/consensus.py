"""One marker set for several subjects: label maps, pooling, and the consensus design.

Subjects recorded with differently named markers are pooled through a label map per subject
(a TSV with columns ``label`` and ``common``, :func:`read_subject_label_map`): a subject's own
labels are renamed to the common names only to pool it with the others, so each subject's own
outputs keep its own labels and the consensus table shows both.  Labels a map does not name
keep their own name.

The consensus design is :func:`~facemotion.regions.design.design_markers` on the pooled
sentences of every subject (:func:`pool_subjects`) with each sentence's subject as its group:
k for the target error is the one definition of :func:`facemotion.regions.target.k_for_error`
on the cross-validated curve pooled over subjects (their sentences weighted by frames), the set
is the candidate with the smallest pooled held-out error, and the intervals come from the
two-stage bootstrap over subjects, then sentences within each drawn subject
(:func:`~facemotion.regions.target.bootstrap_weights`).  Pooled on the markers every subject
has; the others are reported, not dropped silently.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from facemotion.errors import InputError, token
from facemotion.regions.design import MarkerSetDesign, design_markers, subset_errors

#: The columns of a subject's label map.
LABEL_MAP_COLUMNS = ("label", "common")


@dataclass(frozen=True)
class LabelMap:
    """A subject's label map: ``common[label]`` its common name, ``line[label]`` the line of
    the file that says so (for messages), ``source`` the file as the study names it."""

    common: dict[str, str]
    line: dict[str, int]
    source: str


def read_subject_label_map(path, source: str | None = None) -> LabelMap:
    """A subject's label map (module notes), every line checked: the file exists, its columns
    are exactly ``label`` and ``common``, no cell is empty, no label is mapped twice and no two
    labels are mapped to one common name.  ``source``: how messages name the file."""
    from facemotion.errors import MissingFileError

    p = Path(path)
    name = source or str(p)
    if not p.is_file():
        raise MissingFileError(f"label map {name}: file not found")
    try:
        table = pd.read_csv(p, sep="\t", dtype=str, keep_default_na=False,
                            encoding="utf-8-sig")
    except Exception as exc:  # pandas raises many kinds for malformed files
        from facemotion.errors import exception_detail

        raise InputError(f"label map {name}: cannot be parsed as TSV "
                         f"({exception_detail(exc)})") from None
    if tuple(table.columns) != LABEL_MAP_COLUMNS:
        raise InputError(f"label map {name}: columns must be exactly "
                         f"{', '.join(LABEL_MAP_COLUMNS)} (tab-separated), found "
                         f"{', '.join(token(c) for c in table.columns)}")
    common: dict[str, str] = {}
    line: dict[str, int] = {}
    owner: dict[str, str] = {}
    for i, (label, name_) in enumerate(zip(table["label"], table["common"], strict=True),
                                       start=2):
        label, name_ = label.strip(), name_.strip()
        if not label or not name_:
            raise InputError(f"label map {name}, line {i}: empty label or common name")
        if label in common:
            raise InputError(f"label map {name}, line {i}: label {token(label)} is mapped "
                             f"twice (first on line {line[label]})")
        if name_ in owner:
            raise InputError(f"label map {name}, line {i}: labels {token(owner[name_])} and "
                             f"{token(label)} are both mapped to {token(name_)}")
        common[label], line[label], owner[name_] = name_, i, label
    return LabelMap(common, line, name)


def common_labels(labels: Sequence[str], label_map: LabelMap | None, known=()) -> list[str]:
    """``labels`` under their common names.  A map's label that is neither among ``labels`` nor
    ``known`` (e.g. the subject's head markers) is refused, naming the map's line; so is a
    common name that another of the subject's markers keeps as its own."""
    labels = [str(m) for m in labels]
    if label_map is None:
        return labels
    m = label_map
    present = set(labels) | {str(k) for k in known}
    for label, ln in m.line.items():
        if label not in present:
            raise InputError(f"label map {m.source}, line {ln}: label {token(label)} is not a "
                             "marker of the subject")
    out = [m.common.get(x, x) for x in labels]
    for x, c in zip(labels, out, strict=True):
        if x not in m.common and out.count(c) > 1:
            other = next(y for y in labels if y in m.common and m.common[y] == c)
            raise InputError(f"label map {m.source}, line {m.line[other]}: maps "
                             f"{token(other)} to {token(c)}, which the subject's own marker "
                             f"{token(x)} is already called")
    return out


def pool_subjects(parts: Sequence[tuple[str, object, list[str]]]):
    """Stack several subjects' ``Displacements`` (subject, displacements, common labels of its
    columns) on the common markers every one has, in the first subject's order.  Returns the
    pooled ``Displacements`` (sentences named ``subject/sentence``, the first subject's rest
    pose), each sentence's subject, the first subject's columns used and the markers left out
    (not in every subject)."""
    from facemotion.ingest.displacements import Displacements

    common = [m for m in parts[0][2] if all(m in p[2] for p in parts[1:])]
    if len(common) < 2:
        raise InputError(f"pooling subjects: they share {len(common)} marker name(s); map "
                         "their labels to common names")
    rates = {p[1].rate for p in parts}
    if len(rates) > 1:
        raise InputError(f"subjects: different frame rates {sorted(rates)} Hz; resample first")
    cols = [[p[2].index(m) for m in common] for p in parts]
    offsets = np.cumsum([0] + [len(p[1].sentences) for p in parts])
    d = Displacements(
        np.vstack([p[1].A[:, c] for p, c in zip(parts, cols, strict=True)]), common,
        [f"{p[0]}/{s}" for p in parts for s in p[1].sentences],
        np.concatenate([p[1].row_sentence + o for p, o in zip(parts, offsets, strict=False)]),
        np.concatenate([p[1].row_frame for p in parts]), parts[0][1].rate,
        np.vstack([p[1].fill_mask[:, c] for p, c in zip(parts, cols, strict=True)]),
        np.concatenate([p[1].head_residual for p in parts]), parts[0][1].neutral[cols[0]])
    groups = [p[0] for p in parts for _ in p[1].sentences]
    left_out = sorted({m for p in parts for m in p[2]} - set(common))
    return d, groups, cols[0], left_out


@dataclass(frozen=True)
class SubjectPilot:
    """One subject of a consensus: its id, the dataset its sentences come from, its
    ``Displacements`` under its own labels, the common name of each of its markers, and the
    markers its own design placed (own labels; empty when it has none)."""

    subject: str
    dataset: str
    displacements: object
    common: list[str]
    own_selected: list[str]
    own_error_mm: float = float("nan")


@dataclass
class Consensus:
    """The consensus design (module notes): ``design`` on the pooled data (common names),
    ``markers`` one row per common marker, ``subjects`` one row per subject."""

    design: MarkerSetDesign
    markers: pd.DataFrame
    subjects: pd.DataFrame


def consensus_design(pilots: Sequence[SubjectPilot], **design_options) -> Consensus:
    """One marker set for every subject of ``pilots`` (module notes); ``design_options``:
    :func:`~facemotion.regions.design.design_markers`'s (target_mm, k, resamples, level,
    seed, on_unreached, ...)."""
    if len(pilots) < 2:
        raise InputError(f"consensus: {len(pilots)} subject(s); it pools two or more")
    ids = [p.subject for p in pilots]
    if len(set(ids)) != len(ids):
        twice = sorted({s for s in ids if ids.count(s) > 1})
        raise InputError(f"consensus: subject(s) listed twice: {', '.join(twice)}")
    disp, groups, cols0, left_out = pool_subjects(
        [(p.subject, p.displacements, p.common) for p in pilots])
    ms = design_markers(disp, groups=groups, **design_options)
    ms.neutral = pilots[0].displacements.neutral[cols0]
    ms.settings["not_in_every_subject"] = left_out
    return Consensus(ms, _marker_table(pilots, ms, left_out),
                     _subject_table(pilots, ms, disp, groups))


def _marker_table(pilots, ms: MarkerSetDesign, left_out: list[str]) -> pd.DataFrame:
    """ms.per_marker, plus how many subjects' own designs placed each marker and each
    subject's own label; markers not in every subject as rows of their own."""
    per = ms.per_marker.copy()
    extra = pd.DataFrame({"marker": left_out, "role": "not in every subject", "order": 0})
    per = pd.concat([per, extra], ignore_index=True) if left_out else per
    placed = {m: 0 for m in per["marker"]}
    own = {m: [] for m in per["marker"]}
    for p in pilots:
        names = dict(zip(p.displacements.labels, p.common, strict=True))
        for lab in p.own_selected:
            placed[names[lab]] += 1
        for lab, c in names.items():
            own[c].append(f"{p.subject}:{lab}")
    per["placed_by_subjects"] = [placed[m] for m in per["marker"]]
    per["subject_labels"] = [",".join(own[m]) for m in per["marker"]]
    return per


def _subject_table(pilots, ms: MarkerSetDesign, disp, groups) -> pd.DataFrame:
    """Per subject: its sentences, its own design (k, placed markers, expected error) and the
    consensus set's cross-validated held-out error on its sentences (frame-weighted mean 3-D
    error over the predicted markers, the pooled measure restricted to that subject)."""
    labels = list(disp.labels)
    subset = [labels.index(m) for m in ms.selected]
    sums, frames = subset_errors(disp, subset)
    g = np.asarray(groups)
    rest = len(labels) - len(subset)
    rows = []
    for p in pilots:
        mine = g == p.subject
        rows.append({
            "subject": p.subject, "dataset": p.dataset, "sentences": int(mine.sum()),
            "own_k": len(p.own_selected), "own_selected": ",".join(p.own_selected),
            "own_expected_error_mm": float(p.own_error_mm),
            "consensus_error_mm": float(sums[mine].sum() / (frames[mine].sum() * rest))})
    return pd.DataFrame(rows)
