"""One path by which every recording (virtual or real) enters the analysis.

read -> check labels -> validate (units, length, outliers: :mod:`facemotion.ingest.validation`) ->
remove head motion -> select markers -> fill gaps -> displacements.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.ingest.copy_fill import copy_fill
from facemotion.ingest.displacements import (
    Displacements,
    build_displacements,
    check_same_take_layout,
    split_roles,
)
from facemotion.ingest.segments import Segment, cut
from facemotion.io.recording import Recording, finite_samples

if TYPE_CHECKING:
    from facemotion.ingest.validation import Limits

# read_recording, align_head, fill_gaps and the validation are imported in the stages that use
# them: a job that only splits a dataset's rows (split_roles) does not load the readers or scipy.

log = logging.getLogger("facemotion")


@dataclass
class LoadedDataset:
    """A dataset loaded by :func:`load_dataset`: A for all sentences (training first), the gap
    report (one row per marker), the sentences table (file, role, frames, head-fit residual),
    and the masks behind the gap figure."""

    displacements: Displacements
    gap_report: pd.DataFrame
    sentences: pd.DataFrame
    time_s: np.ndarray        # (F,) time of each frame in the concatenated recording
    missing: np.ndarray       # (F, n) bool, missing before filling
    filled: np.ndarray        # (F, n) bool, filled (by us or the producer)
    sentence_starts_s: list[float]

    @property
    def train(self) -> Displacements:
        """The training sentences' displacements (the rows of A the ranking is made from)."""
        return split_roles(self.displacements, self.sentences)[0]

    @property
    def heldout(self) -> Displacements | None:
        """The held-out sentences' displacements, or None without held-out sentences."""
        return split_roles(self.displacements, self.sentences)[1]


def _aggregate_gap_reports(reports: list[pd.DataFrame]) -> pd.DataFrame:
    cat = pd.concat(reports, ignore_index=True)
    g = cat.groupby("marker", sort=False)
    out = pd.DataFrame({
        "marker": list(g.groups),
        "frames": g["frames"].sum().to_numpy(),
        "missing_frames": g["missing_frames"].sum().to_numpy(),
        "longest_gap_frames": g["longest_gap_frames"].max().to_numpy(),
        "n_gaps": g["n_gaps"].sum().to_numpy(),
        "filled_frames": g["filled_frames"].sum().to_numpy(),
    })
    out.insert(3, "missing_fraction", out["missing_frames"] / out["frames"])
    methods = g["fill_method"].agg(
        lambda s: "+".join(sorted({m for v in s for m in str(v).split("+") if m != "none"}))
        or "none")
    out["fill_method"] = methods.to_numpy()
    return out


def load_dataset(recordings: list[str], fmt: str, *, units: str | None = None,
                 head_markers: list[str] = (), exclude_markers: list[str] = (),
                 include_markers: list[str] = (), train: list[int], heldout: list[int],
                 max_interp_s: float = 0.1, long_gaps: str = "pca",
                 neutral: str = "first_frame", limits: Limits | None = None,
                 sentences: list | None = None,
                 subject_prefix: str | None = None,
                 rate: float | None = None,
                 copy_markers: list[tuple[str, str]] = (),
                 markers_named_in: str = "the subject sheet",
                 takes: dict | None = None, progress: bool = False) -> LoadedDataset:
    """Load the sentences ``train + heldout`` (0-based indices into the sentences).

    The sentences are ``recordings`` (one file each) or, when given, ``sentences``: intervals
    of the takes (:class:`~facemotion.ingest.segments.Segment` or its ``to_param`` dict), each
    take read once and cut. The dataset's sentences are ordered training sentences first,
    then held-out ones. Every sentence is checked (:func:`facemotion.ingest.validation.check_take`,
    with ``limits``) on the markers the analysis uses (the analysed and the head markers)
    before head motion is removed.
    ``copy_markers``: (target, source) pairs; the target's missing samples are filled by
    copying the source's displacement in head coordinates (``facemotion.ingest.copy_fill``) before
    the other gaps are filled.
    ``rate``: the declared frame rate (Hz; the sheet's ``rate``), see
    :func:`facemotion.io.registry.read_recording`.
    ``markers_named_in`` says in errors where the marker lists came from (the subject sheet, or
    the arguments of :func:`load`).
    ``takes``: a dict shared by the calls that load several datasets of one subject (the same
    files in another order, e.g. S2a and S2a*): each take is read once and kept there (the
    recordings read are never modified), with the results of the sentences' checks that
    found nothing to warn about. Without it, a take is dropped once cut.
    ``progress``: a progress bar on stderr while the takes are read (only on a terminal).
    """
    from facemotion.ingest.validation import Limits, check_same_shape

    limits = limits or Limits()
    source = TakeSource(fmt, units, subject_prefix, rate)
    items = [Segment.from_param(s) for s in (sentences if sentences is not None
                                              else recordings)]
    chosen = [items[i] for i in list(train) + list(heldout)]
    where = chosen[0].take
    roles = ["train"] * len(train) + ["heldout"] * len(heldout)
    recs = read_sentences(chosen, source, takes, progress)
    labels = recs[0].labels
    keep, used = check_marker_lists(labels, where, head_markers, exclude_markers,
                                    include_markers, markers_named_in)
    recs, checks = check_sentences(recs, chosen, roles, used, limits, source, takes)
    shape_rms = check_same_shape(recs, limits)
    if head_markers:
        recs, residuals = remove_head_motion(recs, list(head_markers), where)
    else:
        residuals = [np.zeros(r.n_frames) for r in recs]
    recs = select_markers(recs, keep, labels)
    missing = [~finite_samples(r.points) for r in recs]
    recs = fill_by_copying(recs, list(copy_markers), where)
    filled_recs, reports = fill_all_gaps(recs, missing, list(copy_markers), max_interp_s,
                                         long_gaps)
    names = [s.name for s in chosen]
    disp = build_displacements(filled_recs, names, neutral=neutral, head_residuals=residuals)
    gap_report = gap_report_table(reports, checks, [used.index(m) for m in keep])
    table = sentences_table(chosen, roles, recs, residuals, checks, shape_rms)
    rate = recs[0].rate
    starts = np.cumsum([0] + [r.n_frames for r in recs])[:-1] / rate
    return LoadedDataset(
        displacements=disp,
        gap_report=gap_report,
        sentences=table,
        time_s=np.arange(sum(r.n_frames for r in recs)) / rate,
        missing=np.concatenate(missing),
        filled=np.concatenate([f.filled for f in filled_recs]),
        sentence_starts_s=[float(s) for s in starts],
    )


@dataclass(frozen=True)
class TakeSource:
    """How a dataset's takes are read: format, the sheet's units and the subject's prefix."""

    fmt: str
    units: str | None = None
    subject_prefix: str | None = None
    rate: float | None = None


def progress_bar(total: int, what: str, show: bool, unit: str = "take"):
    """A progress bar on stderr (tqdm) when ``show`` and stderr is a terminal, else None (a
    disabled bar when stderr is not a terminal: silent)."""
    if not show:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm is a dependency; a trimmed install just shows no bar
        return None
    import sys

    return tqdm(total=total, desc=what, unit=unit, file=sys.stderr, disable=None,
                leave=False)


def read_sentences(chosen: list[Segment], source: TakeSource,
                   takes: dict | None = None, progress: bool = False) -> list[Recording]:
    """Read each take once and cut the sentences ``chosen`` from it.  ``progress``: a bar
    on stderr while reading, when stderr is a terminal."""
    from facemotion.io.registry import read_recording

    shared = takes is not None
    takes = {} if takes is None else takes
    recs = []
    n_takes, n_read = len(dict.fromkeys(s.take for s in chosen)), 0
    bar = progress_bar(n_takes, "reading takes", progress)
    for i, seg in enumerate(chosen):
        key = (seg.take, source.fmt, source.units, source.subject_prefix, source.rate)
        if key not in takes:
            n_read += 1
            log.info("reading %s (%d/%d)", seg.take, n_read, n_takes)
            if bar is not None:
                bar.set_postfix_str(Path(seg.take).name, refresh=True)
            takes[key] = read_recording(seg.take, source.fmt, units=source.units,
                                        subject_prefix=source.subject_prefix,
                                        rate=source.rate)
            if bar is not None:
                bar.update(1)
        recs.append(cut(takes[key], seg))
        if not seg.whole:
            log.info("sentence %d/%d %r: %s, %.4f-%.4f s, %d frames", i + 1, len(chosen),
                     seg.name, seg.take, seg.start_s, seg.end_s, recs[-1].n_frames)
    if bar is not None:
        bar.close()
    if not shared:
        takes.clear()
    for rec in recs[1:]:
        check_same_take_layout(rec, recs[0])
    return recs


def check_marker_lists(labels: list[str], where: str, head_markers=(), exclude_markers=(),
                       include_markers=(), markers_named_in: str = "the subject sheet"
                       ) -> tuple[list[str], list[str]]:
    """The analysed markers and the markers the checks use (analysed, then head markers)."""
    for setting, names in (("head_markers", head_markers), ("exclude_markers", exclude_markers),
                           ("include_markers", include_markers)):
        twice = sorted({m for m in names if list(names).count(m) > 1})
        if twice:
            raise InputError(f"{setting} ({markers_named_in}): marker(s) {', '.join(twice)} "
                             "listed twice")
        for m in names:
            if m not in labels:
                raise InputError(f"{where}: marker {m!r} (named in {setting} of "
                                 f"{markers_named_in}) is not in the data")
    keep = [m for m in (include_markers or labels) if m not in set(exclude_markers)]
    if len(keep) < 2:
        raise InputError(f"{where}: fewer than 2 markers left after include/exclude")
    return keep, keep + [m for m in head_markers if m not in set(keep)]


def check_sentences(recs: list[Recording], chosen: list[Segment], roles: list[str],
                    used: list[str], limits: Limits, source: TakeSource,
                    takes: dict | None = None) -> tuple[list[Recording], list]:
    """Each sentence on the markers ``used``, checked (units, length, outliers)."""
    from facemotion.ingest.validation import check_take

    out, checks = [], []
    for rec, seg, role in zip(recs, chosen, roles, strict=True):
        # a sentence checked clean for another dataset of the subject (same interval, markers
        # and limits; nothing to warn about) is not checked again
        checked = ("checked", seg, source.fmt, source.units, source.subject_prefix,
                   source.rate, tuple(used), limits)
        if takes is not None and checked in takes:
            selected, found = rec.select(used), takes[checked]
        else:
            selected, found = check_take(rec.select(used), limits, sheet_units=source.units,
                                         role=role)
            if takes is not None and not found.units_conflict and not found.outliers.any():
                takes[checked] = found
        out.append(selected)
        checks.append(found)
    return out, checks


def remove_head_motion(recs: list[Recording], head_markers: list[str], where: str
                       ) -> tuple[list[Recording], list[np.ndarray]]:
    """Every take aligned to one neutral head configuration; the fits' residuals (mm)."""
    from facemotion.ingest.head_motion import align_head

    if len(head_markers) < 3:
        raise InputError(f"{where}: {len(head_markers)} head marker(s) given "
                         f"({', '.join(head_markers)}); at least 3 are needed")
    ref_rec = recs[0].select(head_markers)
    complete = np.flatnonzero(finite_samples(ref_rec.points).all(axis=1))
    if complete.size == 0:
        raise InputError(f"{where}: no frame has all head markers {', '.join(head_markers)}")
    # Reference: the median head configuration over all takes (one Procrustes step:
    # align every frame to the first take's first complete frame, then take the median),
    # so that one odd first frame (as in tracker output) or a brow raise that moves a
    # forehead marker does not bias every other frame.
    first = ref_rec.points[complete[0]]
    stacked = np.concatenate([  # only the head markers need moving for this
        align_head(rec.select(head_markers), head_markers, reference=first)[0].points
        for rec in recs])
    reference = np.nanmedian(stacked, axis=0)
    aligned, residuals = [], []
    for rec in recs:
        a, res = align_head(rec, head_markers, reference=reference)
        aligned.append(a)
        residuals.append(res)
        log.info("%s: head fit RMS residual mean %.3f mm, max %.3f mm", rec.source,
                 float(np.mean(res)), float(np.max(res)))
    return aligned, residuals


def select_markers(recs: list[Recording], keep: list[str], labels: list[str]
                   ) -> list[Recording]:
    """The takes on the analysed markers ``keep`` only."""
    dropped = [m for m in labels if m not in set(keep)]
    log.info("analysing %d of %d markers: %s", len(keep), len(labels), ", ".join(keep))
    if dropped:
        log.info("left out (sheet's include/exclude_markers): %s", ", ".join(dropped))
    return [r.select(keep) for r in recs]


def fill_by_copying(recs: list[Recording], copy_markers: list[tuple[str, str]], where: str
                    ) -> list[Recording]:
    """The sheet's copy_markers filled from their sources (head coordinates)."""
    recs, copied = copy_fill(recs, copy_markers, where=f"{where}: subject sheet's copy_markers")
    for t, s in copy_markers:
        log.info("marker %s: %d missing samples filled by copying %s's displacement (head "
                 "coordinates)", t, copied[t], s)
    return recs


def fill_all_gaps(recs: list[Recording], missing: list[np.ndarray],
                  copy_markers: list[tuple[str, str]], max_interp_s: float, long_gaps: str
                  ) -> tuple[list[Recording], list[pd.DataFrame]]:
    """Every take's remaining gaps filled; its gap report (copied gaps as before the copy)."""
    from facemotion.ingest.gaps import fill_gaps

    filled_recs, reports = [], []
    for r, miss in zip(recs, missing, strict=True):
        f, rep = fill_gaps(r, max_interp_s=max_interp_s, long_gaps=long_gaps)
        filled_recs.append(f)
        reports.append(report_copies(rep, miss, miss & finite_samples(r.points), r.labels,
                                     copy_markers))
    return filled_recs, reports


def gap_report_table(reports: list[pd.DataFrame], checks: list, cols: list[int]
                     ) -> pd.DataFrame:
    """One row per analysed marker over all takes, with its outlier frames (``cols``: the
    analysed markers' columns in the checks)."""
    gap_report = _aggregate_gap_reports(reports)
    gap_report.insert(len(gap_report.columns) - 2, "outlier_frames",
                      sum(c.outliers[:, cols].sum(axis=0) for c in checks).astype(int))
    return gap_report


def sentences_table(chosen: list[Segment], roles: list[str], recs: list[Recording],
                    residuals: list[np.ndarray], checks: list, shape_rms) -> pd.DataFrame:
    """One row per sentence: file, interval, role, frames, head fit and the checks' findings."""
    return pd.DataFrame({
        "sentence": [s.name for s in chosen],
        "file": [str(s.take) for s in chosen],
        "start_s": [0.0 if s.whole else float(s.start_s) for s in chosen],
        "end_s": [r.n_frames / r.rate if s.whole else float(s.end_s)
                  for s, r in zip(chosen, recs, strict=True)],
        "role": roles,
        "frames": [r.n_frames for r in recs],
        "duration_s": [r.n_frames / r.rate for r in recs],
        "head_fit_rms_mm": [float(np.sqrt(np.mean(np.square(x)))) for x in residuals],
        "head_fit_max_mm": [float(np.max(x)) if len(x) else 0.0 for x in residuals],
        "units": [c.units for c in checks],
        "units_from": [c.units_source for c in checks],
        "units_conflict": [c.units_conflict for c in checks],
        "face_spread_mm": [c.spread_mm for c in checks],
        "shape_rms_mm": shape_rms,
        "outlier_samples": [int(c.outliers.sum()) for c in checks],
    })


def report_copies(rep: pd.DataFrame, miss: np.ndarray, copied: np.ndarray, labels: list[str],
                  pairs: list[tuple[str, str]]) -> pd.DataFrame:
    """The gap report of a take, with the copy-filled targets described as they were before
    the copy (``miss``: missing samples, gaps; ``copied``: the samples copied) and
    'copy:SOURCE' among their fill methods."""
    from facemotion.ingest.gaps import runs

    if not pairs:
        return rep
    rep = rep.copy()
    for t, s in pairs:
        j = labels.index(t)
        i = int(np.flatnonzero(rep["marker"].to_numpy() == t)[0])
        r = runs(miss[:, j])
        rep.loc[i, "missing_frames"] = int(miss[:, j].sum())
        rep.loc[i, "missing_fraction"] = float(miss[:, j].mean()) if len(miss) else 0.0
        rep.loc[i, "longest_gap_frames"] = max((b - a for a, b in r), default=0)
        rep.loc[i, "n_gaps"] = len(r)
        if copied[:, j].any():
            rest = [m for m in str(rep.loc[i, "fill_method"]).split("+") if m != "none"]
            rep.loc[i, "fill_method"] = "+".join([f"copy:{s}"] + rest)
    return rep


def load(paths, *, heldout_sentences=(), fmt: str | None = None, head_markers=(),
         exclude_markers=(), include_markers=(), heldout=None, progress: bool = False,
         **options) -> LoadedDataset:
    """Load takes into one dataset (``facemotion.load``), by the path the workflow uses.

    paths: one file or a list of files (the sentences, in this order).
    heldout_sentences: numbers of the held-out sentences, counting from 1 as the config
        does (1 is the first of ``paths``); the others train.
    heldout: the 0.2 form, counting from 0; deprecated (DeprecationWarning), removed in 0.3.
    progress: a progress bar on stderr while the takes are read (only on a terminal).
    fmt: one of facemotion.io.registry.FORMAT_NAMES; default: from the first file's content
        or suffix (:func:`facemotion.io.registry.infer_format`).
    head_markers: >= 3 markers that move with the head only (removed as rigid motion).
    exclude_markers / include_markers: markers left out of / kept in the analysis.
    options: the other settings of :func:`load_dataset` (``units``, ``subject_prefix``,
        ``rate``, ``max_interp_s``, ``long_gaps``, ``neutral``), with its defaults (those of
        the workflow's config).
    """
    from facemotion.io.registry import infer_format

    paths = [str(paths)] if isinstance(paths, str | Path) else [str(p) for p in paths]
    if not paths:
        raise InputError("paths: no recordings given")
    held, name = _heldout_indices(heldout_sentences, heldout, len(paths))
    train = [i for i in range(len(paths)) if i not in set(held)]
    if not train:
        raise InputError(f"{name}: every recording is held out; at least one must train")
    return load_dataset(paths, fmt or infer_format(paths[0]), head_markers=list(head_markers),
                        exclude_markers=list(exclude_markers),
                        include_markers=list(include_markers), train=train, heldout=held,
                        markers_named_in="the arguments", progress=progress, **options)


def _heldout_indices(numbers, old, n: int) -> tuple[list[int], str]:
    """0-based indices of the held-out sentences from ``heldout_sentences`` (from 1) or the
    deprecated ``heldout`` (from 0), and the argument's name for messages."""
    if old is not None:
        if len(numbers):
            raise InputError("heldout / heldout_sentences: give one of them (heldout_sentences "
                             "counts from 1)")
        import warnings

        warnings.warn("facemotion.load(heldout=...) counts sentences from 0 and is deprecated "
                      "(removed in 0.3); use heldout_sentences=..., counting from 1 as the "
                      "config does", DeprecationWarning, stacklevel=3)
        held, name, first = sorted({int(i) for i in old}), "heldout", 0
    else:
        held, name, first = sorted({int(i) - 1 for i in numbers}), "heldout_sentences", 1
    bad = [i + first for i in held if not 0 <= i < n]
    if bad:
        raise InputError(f"{name}: sentence number(s) {bad} out of range for {n} "
                         f"recording(s) (counting from {first})")
    return held, name
