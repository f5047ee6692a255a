"""The subject sheet (the user's interface to their data) and the datasets built on it.

A subject is one talker: a set of recordings (one file per sentence, or long takes cut into
sentences by the ``segments`` column, see :mod:`facemotion.ingest.segments`), their format,
which markers move rigidly with the head and which to leave out. A dataset is the unit of
analysis: a subject plus which of its sentences train the model and which are held out.
"""

from __future__ import annotations

import glob
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from facemotion.errors import InputError
from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.segments import Segment, segment_subject
from facemotion.io.base import UNITS
from facemotion.io.registry import FORMAT_NAMES
from facemotion.regions.consensus import LabelMap, read_subject_label_map

SHEET_COLUMNS = ("subject", "recordings", "format", "head_markers", "exclude_markers")
OPTIONAL_COLUMNS = ("units", "include_markers", "simulate", "seed", "talker_seed",
                    "n_sentences", "sentence_duration", "segments", "subject_prefix",
                    "copy_markers", "rate", "label_map")
DEFAULT_HELDOUT_FRACTION = 0.25
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def natural_key(text: str) -> list:
    """Sort key that puts ``s2`` before ``s10``."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", str(text))]


def split_labels(value) -> list[str]:
    """A comma-separated cell -> list of labels ('' or NaN -> [])."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return []
    return [v.strip() for v in str(value).split(",") if v.strip()]


@dataclass
class Subject:
    id: str
    recordings: list[str]
    format: str
    head_markers: list[str] = field(default_factory=list)
    exclude_markers: list[str] = field(default_factory=list)
    include_markers: list[str] = field(default_factory=list)
    units: str | None = None
    simulate: str | None = None
    seed: int = 0
    talker_seed: int | None = None
    n_sentences: int | None = None
    sentence_duration: tuple[float, float] | None = None
    segments: list[Segment] | None = None   # sentences cut from the takes; None = whole takes
    segment_sources: list[str] = field(default_factory=list)  # TextGrids / tables read
    subject_prefix: str | None = None
    copy_markers: list[tuple[str, str]] = field(default_factory=list)
    rate: float | None = None   # declared frame rate (Hz), for files timed by time stamps
    label_map: LabelMap | None = None  # its labels -> common names, to pool it with others

    @property
    def sentences(self) -> list[Segment]:
        """The subject's sentences: intervals of its takes, or its whole takes."""
        if self.segments is not None:
            return self.segments
        return [Segment(Path(p).stem, p) for p in self.recordings]

    @property
    def sentence_names(self) -> list[str]:
        return [s.name for s in self.sentences]


@dataclass
class Dataset:
    id: str
    label: str
    subject: str
    train: list[int]
    heldout: list[int]


def _cell(row: pd.Series, col: str):
    value = row.get(col)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    value = str(value).strip()
    return value or None


def read_sheet_table(path: str | Path) -> pd.DataFrame:
    """The sheet as a table of strings, read literally: no comment character (a '#' in a cell
    is part of the cell), no NA spellings (an empty cell is '')."""
    return pd.read_csv(path, sep="\t", dtype=str, keep_default_na=False, encoding="utf-8-sig")


def _labels_cell(row: pd.Series, col: str, where: str, sid: str) -> list[str]:
    labels = split_labels(row.get(col))
    twice = sorted({m for m in labels if labels.count(m) > 1})
    if twice:
        raise InputError(f"{where}: column {col} of subject {sid!r} lists marker(s) "
                         f"{', '.join(twice)} twice")
    return labels


def read_subject_sheet(path: str | Path, shared_data: str | Path | None = None,
                       virtual_dir: str | Path = "results/virtual") -> dict[str, Subject]:
    """Read and check the subject sheet; recordings are resolved relative to the sheet.

    ``{shared_data}`` in a recordings cell is replaced by the configured shared-data folder.
    Subjects with a ``simulate`` design have their recordings under ``virtual_dir``.
    """
    path = Path(path)
    sheet = _checked_table(path)
    subjects: dict[str, Subject] = {}
    for i, row in sheet.iterrows():
        where = f"subject sheet {path}, row {i + 2}"
        sid = _cell(row, "subject")
        if sid is None or not _ID.match(sid):
            raise InputError(f"{where}: subject id {sid!r} must be letters, digits, '_', '.', '-'")
        if sid in subjects:
            raise InputError(f"{where}: duplicate subject {sid!r}")
        subjects[sid] = subject_from_row(row, sid, where, path, shared_data, virtual_dir)
    return subjects


def _checked_table(path: Path) -> pd.DataFrame:
    """The sheet's table, with the expected columns and at least one subject."""
    if not path.is_file():
        raise InputError(f"subject sheet {path}: file not found")
    try:
        sheet = read_sheet_table(path)
    except Exception as exc:  # pandas raises many kinds for malformed files
        detail = str(exc).strip().splitlines()[0][:120] if str(exc).strip() else ""
        raise InputError(f"subject sheet {path}: cannot be parsed as TSV "
                         f"({type(exc).__name__}{': ' + detail if detail else ''})") from None
    missing = [c for c in SHEET_COLUMNS if c not in sheet.columns]
    if missing:
        raise InputError(f"subject sheet {path}: missing column(s) {missing}; "
                         f"expected {list(SHEET_COLUMNS)} (tab-separated)")
    unknown = [c for c in sheet.columns if c not in SHEET_COLUMNS + OPTIONAL_COLUMNS]
    if unknown:
        raise InputError(f"subject sheet {path}: unknown column(s) {unknown}")
    if sheet.empty:
        raise InputError(f"subject sheet {path}: no subjects")
    return sheet


def subject_from_row(row: pd.Series, sid: str, where: str, path: Path,
                     shared_data: str | Path | None = None,
                     virtual_dir: str | Path = "results/virtual") -> Subject:
    """One row of the sheet at ``path`` as a Subject, every cell checked."""
    fmt = (_cell(row, "format") or "").lower()
    if fmt not in FORMAT_NAMES:
        raise InputError(f"{where}: unknown format {fmt!r} for subject {sid!r} "
                         f"(use one of {', '.join(FORMAT_NAMES)})")
    units = _cell(row, "units")
    if units is not None and units not in UNITS:
        raise InputError(f"{where}: unknown units {units!r} for subject {sid!r} "
                         f"(use one of {', '.join(UNITS)})")
    design = _cell(row, "simulate")
    copy_markers = parse_copy_markers(_cell(row, "copy_markers"), f"{where}: copy_markers")
    spec = None
    if design is not None:
        from facemotion.virtual.designs import get_design

        spec = get_design(design, f"{where}: simulate")
        # the S1 design records marker 13 only in each sentence's first frame; the
        # authors filled it by copying 11, so that is its sheet's default
        copy_markers = copy_markers or list(spec.copy_markers)
    seed = _int_cell(row, "seed", where, 0)
    talker_seed = _int_cell(row, "talker_seed", where, None)
    n_sentences = _int_cell(row, "n_sentences", where, None)
    sentence_duration = _sentence_duration(_cell(row, "sentence_duration"), where)
    if spec is not None:
        recordings, n_sentences = simulated_recordings(spec, design, fmt, n_sentences, sid,
                                                       virtual_dir, where)
    else:
        recordings = recorded_files(_cell(row, "recordings"), fmt, sid, path.parent,
                                    shared_data, where)
    prefix = _cell(row, "subject_prefix")
    rate = None
    if _cell(row, "rate") is not None:
        from facemotion.io.registry import check_rate

        rate = check_rate(_cell(row, "rate"), f"{where} (subject {sid!r})")
    segments, sources = None, []
    if _cell(row, "segments") is not None:
        if design is not None:
            raise InputError(f"{where}: simulated subject {sid!r} has one file per "
                             "sentence; leave its segments cell empty")
        segments, sources = segment_subject(
            _cell(row, "segments"), recordings, fmt, path.parent,
            f"{where} (subject {sid!r})", shared_data=shared_data, subject_prefix=prefix)
    return Subject(
        id=sid, recordings=recordings, format=fmt, segments=segments,
        segment_sources=sources, subject_prefix=prefix,
        head_markers=_labels_cell(row, "head_markers", where, sid),
        exclude_markers=_labels_cell(row, "exclude_markers", where, sid),
        include_markers=_labels_cell(row, "include_markers", where, sid),
        units=units, simulate=design, seed=seed, talker_seed=talker_seed,
        n_sentences=n_sentences, sentence_duration=sentence_duration,
        copy_markers=copy_markers, rate=rate,
        label_map=_label_map(_cell(row, "label_map"), path.parent, where, sid))


def _label_map(cell: str | None, sheet_dir: Path, where: str, sid: str) -> LabelMap | None:
    """The subject's label map (a TSV relative to the sheet), read and checked now so that a
    bad map stops the study before any job runs."""
    if cell is None:
        return None
    full = Path(cell) if Path(cell).is_absolute() else sheet_dir / cell
    try:
        return read_subject_label_map(full)
    except InputError as e:
        raise type(e)(f"{where} (subject {sid!r}): {e}") from None


def _sentence_duration(duration: str | None, where: str) -> tuple[float, float] | None:
    """'1.5-4' -> (1.5, 4.0) seconds, checked 0 < low <= high."""
    if duration is None:
        return None
    try:
        lo, hi = (float(x) for x in duration.split("-"))
    except ValueError:
        raise InputError(f"{where}: sentence_duration {duration!r} must look like "
                         "'1.5-4' (seconds)") from None
    if not 0 < lo <= hi:
        raise InputError(f"{where}: sentence_duration {duration!r} must satisfy "
                         "0 < low <= high")
    return (lo, hi)


def simulated_recordings(spec, design: str, fmt: str, n_sentences: int | None, sid: str,
                         virtual_dir: str | Path, where: str) -> tuple[list[str], int]:
    """The files a simulated subject's design writes under ``virtual_dir`` (one a sentence),
    and their number."""
    written = dict(spec.formats)
    if fmt not in written:
        raise InputError(f"{where}: simulated subject {sid!r} (design {design!r}) is "
                         f"written as {' or '.join(written)}, not {fmt!r}")
    n = n_sentences or spec.sentences
    if n is None:
        raise InputError(f"{where}: design {design!r} needs n_sentences")
    if n < 1:
        raise InputError(f"{where}: n_sentences must be at least 1")
    return [str(Path(virtual_dir) / sid / f"{sid}_s{j + 1:02d}.{written[fmt]}")
            for j in range(n)], n


def recorded_files(pattern: str | None, fmt: str, sid: str, sheet_dir: Path,
                   shared_data: str | Path | None, where: str) -> list[str]:
    """The files of a recordings cell (a file or a glob, relative to the sheet), each a file."""
    if pattern is None:
        raise InputError(f"{where}: subject {sid!r} has no recordings")
    if "{shared_data}" in pattern:
        if shared_data is None:
            raise InputError(f"{where}: recordings use {{shared_data}} but the setting "
                             "'shared_data' is not set")
        pattern = pattern.replace("{shared_data}", str(shared_data))
    full = pattern if Path(pattern).is_absolute() else str(sheet_dir / pattern)
    if glob.has_magic(full):
        recordings = sorted(glob.glob(full), key=natural_key)
        if not recordings:
            raise InputError(f"{where}: recordings {pattern!r} of subject {sid!r} "
                             f"match no file (looked for {full})")
    else:
        if Path(full).is_dir():
            raise InputError(f"{where}: recordings {full} of subject {sid!r} is a "
                             "directory; give a file or a glob such as "
                             f"{Path(pattern) / ('*.' + fmt)}")
        if not Path(full).is_file():
            raise InputError(f"{where}: recording file {full} of subject {sid!r} "
                             "not found")
        recordings = [full]
    dirs = [r for r in recordings if not Path(r).is_file()]
    if dirs:
        raise InputError(f"{where}: recordings {pattern!r} of subject {sid!r} match "
                         f"{dirs[0]}, which is not a file")
    return [str(Path(p)) for p in recordings]


def _int_cell(row, col, where, default):
    value = _cell(row, col)
    if value is None:
        return default
    try:
        return int(value)
    except ValueError:
        raise InputError(f"{where}: {col} {value!r} must be an integer") from None


def parse_sentences(spec, n: int, setting: str) -> list[int]:
    """Sentence selection -> 0-based indices.

    ``spec`` is a list of 1-based sentence numbers, or a string of comma-separated items
    ``a-b`` (inclusive range), ``a``, ``first:N`` or ``last:N``.
    """
    if isinstance(spec, int):
        spec = [spec]
    items: list[int] = []
    parts = spec if isinstance(spec, list) else str(spec).split(",")
    for part in parts:
        if isinstance(part, int):
            items.append(part)
            continue
        part = part.strip()
        m_first = re.fullmatch(r"first:(\d+)", part)
        m_last = re.fullmatch(r"last:(\d+)", part)
        m_range = re.fullmatch(r"(\d+)-(\d+)", part)
        if m_first:
            items.extend(range(1, int(m_first.group(1)) + 1))
        elif m_last:
            k = int(m_last.group(1))
            items.extend(range(n - k + 1, n + 1))
        elif m_range:
            a, b = int(m_range.group(1)), int(m_range.group(2))
            if a > b:
                raise InputError(f"setting {setting}: range {part!r} runs backwards")
            items.extend(range(a, b + 1))
        elif part.isdigit():
            items.append(int(part))
        else:
            raise InputError(f"setting {setting}: cannot read sentence selection {part!r} "
                             "(use 'a-b', 'first:N', 'last:N' or numbers)")
    bad = [i for i in items if not 1 <= i <= n]
    if bad:
        raise InputError(f"setting {setting}: sentence(s) {bad} outside 1..{n}")
    if len(set(items)) != len(items):
        raise InputError(f"setting {setting}: sentences listed twice")
    return [i - 1 for i in items]


def n_heldout(n: int, heldout_fraction: float) -> int:
    """Sentences held out by default: the fraction of n, rounded; 0 when the fraction is 0;
    otherwise at least one and at most n - 1 (a subject with one sentence holds none out)."""
    if not 0 <= heldout_fraction < 1:
        raise InputError(f"setting heldout_fraction: must be in [0, 1), got {heldout_fraction!r}")
    if heldout_fraction == 0 or n < 2:
        return 0
    return min(max(int(round(heldout_fraction * n)), 1), n - 1)


def resolve_datasets(subjects: dict[str, Subject], datasets_cfg: dict | None,
                     heldout_fraction: float = DEFAULT_HELDOUT_FRACTION,
                     default_per_subject: bool = True) -> dict[str, Dataset]:
    """Datasets: one per subject by default, plus those defined in ``config.datasets``.

    When nothing says otherwise the last ``heldout_fraction`` of a subject's sentences
    (:func:`n_heldout`: rounded, at least one when the subject has two or more, none when the
    fraction is 0) is held out for evaluation.
    """
    out: dict[str, Dataset] = {}

    def default_split(n: int) -> tuple[list[int], list[int]]:
        n_held = n_heldout(n, heldout_fraction)
        return list(range(n - n_held)), list(range(n - n_held, n))

    if default_per_subject:
        for sid, subj in subjects.items():
            train, held = default_split(len(subj.sentences))
            out[sid] = Dataset(sid, sid, sid, train, held)
    for did, spec in (datasets_cfg or {}).items():
        setting = f"datasets.{did}"
        if not _ID.match(str(did)):
            raise InputError(f"setting {setting}: dataset id must be letters, digits, "
                             "'_', '.', '-'")
        sid = spec.get("subject")
        if sid not in subjects:
            raise InputError(f"setting {setting}.subject: unknown subject {sid!r} "
                             f"(sheet has {', '.join(subjects)})")
        n = len(subjects[sid].sentences)
        if "train" in spec:
            train = parse_sentences(spec["train"], n, f"{setting}.train")
        else:
            train = default_split(n)[0]
        if "heldout" in spec:
            held = parse_sentences(spec["heldout"], n, f"{setting}.heldout")
        else:
            held = [i for i in range(n) if i not in set(train)]
            if "train" not in spec:
                held = default_split(n)[1]
        overlap = sorted(set(train) & set(held))
        if overlap:
            raise InputError(f"setting {setting}: sentences {[i + 1 for i in overlap]} are "
                             "both training and held out")
        if not train:
            raise InputError(f"setting {setting}.train: no training sentences")
        out[str(did)] = Dataset(str(did), str(spec.get("label", did)), sid, train, held)
    return out


def dataset_params(subjects: dict[str, Subject], datasets: dict[str, Dataset],
                   dataset: str, names: dict[str, str] | None = None) -> dict:
    """Everything about a dataset that its outputs depend on (the loading rule's params):
    the sheet's row of its subject and its sentences (1-based, as in the config); takes are
    named by ``names`` (:func:`recorded_names`) where it has them."""
    ds = datasets[dataset]
    subj = subjects[ds.subject]
    names = names or {}
    segments = None if subj.segments is None else [
        {**s.to_param(), "take": names.get(s.take, s.take)} for s in subj.segments]
    return {
        "dataset": ds.id,
        "label": ds.label,
        "subject": subj.id,
        "format": subj.format,
        "units": subj.units,
        "head_markers": subj.head_markers,
        "exclude_markers": subj.exclude_markers,
        "include_markers": subj.include_markers,
        "copy_markers": [f"{t}={s}" for t, s in subj.copy_markers],
        "train": [i + 1 for i in ds.train],
        "heldout": [i + 1 for i in ds.heldout],
        "sentence_names": subj.sentence_names,
        "subject_prefix": subj.subject_prefix,
        "segments": segments,
        # only when declared, so that the params of sheets without it stay as they were
        **({"rate": subj.rate} if subj.rate is not None else {}),
    }


def simulation_params(subject: Subject, shared_data: str | Path) -> dict:
    """What a virtual subject's files depend on (the simulating rule's params)."""
    return {
        "design": subject.simulate,
        "seed": subject.seed,
        "talker_seed": subject.talker_seed,
        "n_sentences": subject.n_sentences,
        "sentence_duration": subject.sentence_duration,
        "format": subject.format,
        "shared_data": str(shared_data),
    }


def virtual_talkers(n_talkers: int, design: str, n_sentences: int, heldout_fraction: float,
                    virtual_dir: str | Path) -> tuple[dict[str, Subject], dict[str, Dataset]]:
    """The sweep over virtual talkers (setting ``virtual_talkers``): subjects V01, V02, ...
    of one design, each its own talker (talker seed 1, 2, ...), one dataset each with the
    last ``heldout_fraction`` of its sentences held out."""
    from facemotion.virtual.designs import HEAD_LABELS, get_design

    spec = get_design(design, "setting virtual_talkers.design")
    if spec.dense:
        raise InputError(f"setting virtual_talkers.design: {design!r} is a dense design; "
                         "the talker sweep uses the 57-marker talker's designs")
    subjects, datasets = {}, {}
    for i in range(n_talkers):
        sid = f"V{i + 1:02d}"
        subjects[sid] = Subject(
            id=sid,
            recordings=[str(Path(virtual_dir) / sid / f"{sid}_s{j + 1:02d}.c3d")
                        for j in range(n_sentences)],
            format="c3d", head_markers=list(HEAD_LABELS), exclude_markers=list(HEAD_LABELS),
            simulate=design, seed=1000 + i, talker_seed=i + 1, n_sentences=n_sentences,
            copy_markers=list(spec.copy_markers))
        held = n_heldout(n_sentences, heldout_fraction)
        datasets[sid] = Dataset(sid, sid, sid, list(range(n_sentences - held)),
                                list(range(n_sentences - held, n_sentences)))
    return subjects, datasets


def recorded_name(path: str | Path, root: str | Path, sheet_dir: str | Path,
                  shared_data: str | Path | None = None) -> str:
    """How the study records an input file, so that its outputs do not depend on the folder
    it runs in: ``{shared_data}/...`` under the shared-data folder, a path relative to the
    study root under it, ``{sheet}/...`` (relative to the subject sheet's folder) under the
    sheet's folder, else the absolute path (the same wherever the study runs)."""
    full = Path(os.path.abspath(path))
    for token, base in (("{shared_data}", shared_data), (None, root), ("{sheet}", sheet_dir)):
        if base is None:
            continue
        try:
            rel = full.relative_to(os.path.abspath(base))
        except ValueError:
            continue
        return rel.as_posix() if token is None else f"{token}/{rel.as_posix()}"
    return full.as_posix()


def recorded_names(subjects: dict[str, Subject], root: str | Path, sheet_dir: str | Path,
                   shared_data: str | Path | None = None) -> dict[str, str]:
    """:func:`recorded_name` of every recording and segmentation file of ``subjects``."""
    return {f: recorded_name(f, root, sheet_dir, shared_data)
            for s in subjects.values() for f in [*s.recordings, *s.segment_sources]}


def consensus_datasets(subjects: dict[str, Subject], design_datasets, enabled: bool,
                       file_labels: dict[str, list[str]]) -> dict[str, str]:
    """The cross-subject consensus (setting eval.consensus): each subject's first dataset with
    a design, subject -> dataset ({} when not enabled).  Each subject's label map is checked
    against the markers of its files now (``file_labels``), so a map naming a marker the
    subject lacks stops the study before any job runs."""
    from facemotion.regions.consensus import common_labels

    if not enabled:
        return {}
    chosen: dict[str, str] = {}
    for d, ds in design_datasets.items():
        chosen.setdefault(ds.subject, d)
    if len(chosen) < 2:
        raise InputError(f"setting eval.consensus: pools two subjects or more with a design; "
                         f"the study has {len(chosen)}")
    for sid in chosen:
        try:
            common_labels(file_labels[sid], subjects[sid].label_map)
        except InputError as e:
            raise InputError(f"subject {sid!r}: {e}") from None
    return chosen


def consensus_params(subjects: dict[str, Subject], chosen: dict[str, str], root, sheet_dir,
                     shared_data=None) -> list[dict]:
    """What the consensus job depends on, per subject: its dataset and its label map's content
    (so that the job reruns when a map's content changes), the map named as the study records
    it."""
    out = []
    for sid, d in chosen.items():
        lm = subjects[sid].label_map
        out.append({"subject": sid, "dataset": d, "head_markers": subjects[sid].head_markers,
                    "label_map": None if lm is None else {
                        "source": recorded_name(lm.source, root, sheet_dir, shared_data),
                        "common": lm.common, "line": lm.line}})
    return out
