"""The formats the study reads, in one place: their readers, writers, suffixes and units.

``FORMATS`` is the one list of formats: the subject sheet's ``format`` column, the command
line's ``--format`` choices, the docs' format table and :func:`read_recording` all come from
it. Each format's module under :mod:`facemotion.io` holds its reader (and writer, when the
study writes the format); it is imported only when a file of that format is read.

Every reader returns a :class:`~facemotion.io.recording.Recording` in millimetres with NaN for
missing samples. A marker missing in every frame is kept (all NaN); the gap check
(:mod:`facemotion.ingest.gaps`) reports it. Writers write to a temporary file beside the target
and rename it (:mod:`facemotion.io.atomic`).

Units: a file that states its units (C3D ``POINT:UNITS``, the TRC header's ``Units``, Motive's
``Length Units``) is read in them; the ``units`` argument (the subject sheet's) only applies to
a file that does not say. The recording keeps the units used and where they came from;
:mod:`facemotion.ingest.validation` reports a sheet that disagrees with the file.

The readers are strict about layout, because a file that is cut short or has a field missing
can otherwise read back as a plausible, different recording: each such file is an error naming
the file and the line. Messages never quote a file's content beyond a short token.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from facemotion.errors import InputError, token
from facemotion.io.recording import Recording


@dataclass(frozen=True)
class Format:
    """One file format: what writes it, where its reader lives, how its units are known."""

    name: str                  # the sheet's ``format`` value, the CLI's ``--format``
    title: str                 # the format and the systems that write it
    module: str                # facemotion.io.<module>
    reader: str                # function of the module: (path, units=None) -> Recording
    suffixes: tuple[str, ...] = ()    # told by its suffix when no format is given
    label_reader: str | None = None   # reads the labels from the header alone (else: the file)
    writer: str | None = None          # function of the module: (path, Recording) -> None
    units: str = ""            # where the units come from
    rate_from_times: bool = False  # the rate is a time column's (a declared rate overrides it)

    def _function(self, name: str) -> Callable:
        return getattr(importlib.import_module(f"facemotion.io.{self.module}"), name)

    def read(self, path, units: str | None = None, rate: float | None = None) -> Recording:
        """The file read; ``rate`` (Hz, declared by the sheet or ``--rate``) replaces the rate
        of a format that takes it from time stamps, and must match any other file's rate."""
        if rate is not None:
            rate = check_rate(rate, f"{path} (declared rate)")
        if rate is not None and self.rate_from_times:
            return self._function(self.reader)(path, units=units, rate=rate)
        rec = self._function(self.reader)(path, units=units)
        self.check_stated_rate(path, rec.rate, rate)
        return rec

    def check_stated_rate(self, path, stated: float, declared: float | None) -> None:
        """A declared rate must equal the rate the file states."""
        if declared is not None and abs(stated - declared) > 1e-6 * declared:
            raise InputError(f"{path}: the file states {stated:g} Hz but the declared rate "
                             f"is {declared:g} Hz; declare no rate for a {self.name} file, or "
                             "its own")

    def labels(self, path) -> list[str]:
        if self.label_reader is None:
            return self.read(path).labels
        return self._function(self.label_reader)(path)

    def write(self, path, rec: Recording) -> None:
        if self.writer is None:
            written = ", ".join(f.name for f in FORMATS.values() if f.writer)
            raise InputError(f"{path}: the study does not write {self.name} files "
                             f"(it writes {written})")
        self._function(self.writer)(path, rec)


FORMATS: dict[str, Format] = {f.name: f for f in (
    Format("c3d", "C3D, as Vicon, Qualisys, OptiTrack, Motion Analysis and others write it "
           "(read with ezc3d)", "c3d", "read_c3d", (".c3d",), "read_c3d_labels", "write_c3d",
           "the file's POINT:UNITS; the sheet's for a file without them"),
    Format("trc", "TRC (OpenSim, Motion Analysis)", "trc", "read_trc", (".trc",),
           "read_trc_labels", "write_trc",
           "the header's Units; the sheet's for a file without them"),
    Format("csv", "wide CSV: time (s), then <label>_x, <label>_y, <label>_z", "wide_csv",
           "read_csv", (".csv",), "read_csv_labels", "write_csv", "the sheet's, else mm"),
    Format("qualisys_tsv", "Qualisys Track Manager TSV export of 3-D trajectories",
           "qualisys", "read_qualisys_tsv", units="mm (QTM exports mm)"),
    Format("optitrack_csv", "OptiTrack Motive CSV export", "optitrack", "read_optitrack_csv",
           units="the file's Length Units; the sheet's for a file without them"),
    Format("openface_csv", "OpenFace 2.x landmark CSV (FeatureExtraction)", "openface",
           "read_openface_csv", label_reader="read_openface_labels",
           writer="write_openface_csv", units="mm (OpenFace's 3-D landmarks)",
           rate_from_times=True),
)}
#: The format names, in the registry's order.
FORMAT_NAMES: tuple[str, ...] = tuple(FORMATS)
#: Formats told by the file's suffix when neither the caller nor the content tells.
SUFFIX_FORMATS = {s: f.name for f in FORMATS.values() for s in f.suffixes}


def get_format(fmt: str, where: str = "format") -> Format:
    """The format named ``fmt`` (any case); InputError naming ``where`` otherwise."""
    key = str(fmt).strip().lower()
    if key not in FORMATS:
        raise InputError(f"{where}: unknown format {token(fmt)} (supported: "
                         f"{', '.join(FORMAT_NAMES)})")
    return FORMATS[key]


def check_rate(rate, where: str) -> float:
    """A declared frame rate (Hz) as a positive finite float; InputError naming ``where``."""
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise InputError(f"{where}: rate {token(rate)} is not a number (Hz)") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{where}: rate must be a positive number of Hz, got {token(rate)}")
    return value


#: QTM TSV header variables, one of which starts a QTM export.
_QTM_KEYS = ("NO_OF_FRAMES", "FILE_VERSION", "NO_OF_CAMERAS", "NO_OF_MARKERS", "FREQUENCY")


def format_from_content(head: bytes) -> str | None:
    """The format a file's first bytes show, or None: C3D by its header's key byte (0x50),
    TRC by ``PathFileType``, a Motive export by ``Format Version``, a QTM export by its
    header variables, an OpenFace CSV by its ``frame``, ``timestamp`` and ``success``
    columns, a wide CSV by its ``time`` column."""
    if len(head) >= 512 and head[1] == 0x50 and head[0] >= 2:
        return "c3d"
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    first = text.split("\n", 1)[0].rstrip("\r")
    if first.startswith("PathFileType"):
        return "trc"
    if first.split(",", 1)[0].strip() == "Format Version":
        return "optitrack_csv"
    if first.split("\t", 1)[0].strip() in _QTM_KEYS:
        return "qualisys_tsv"
    columns = {c.strip() for c in first.split(",")}
    if {"frame", "timestamp", "success"} <= columns:
        return "openface_csv"
    if first.split(",", 1)[0].strip() == "time":
        return "csv"
    return None


def infer_format(path) -> str:
    """The format of a file from its content (:func:`format_from_content`), else from its
    suffix (.c3d, .trc, .csv, any case); InputError when neither tells."""
    p = Path(path)
    head = b""
    if p.is_file():
        try:
            with open(p, "rb") as fh:
                head = fh.read(4096)
        except OSError:
            head = b""
    found = format_from_content(head)
    if found is not None:
        return found
    suffix = p.suffix.lower()
    if suffix not in SUFFIX_FORMATS:
        raise InputError(f"{path}: cannot tell the format from the content or the suffix "
                         f"{p.suffix or '(none)'!r}; give the format "
                         f"({', '.join(FORMAT_NAMES)})")
    return SUFFIX_FORMATS[suffix]


def read_recording(path, fmt: str | None = None, units: str | None = None,
                   subject_prefix: str | None = None, rate: float | None = None) -> Recording:
    """Read one take (``facemotion.read``): labelled marker trajectories in mm.

    fmt: one of ``FORMAT_NAMES``; default: from the file's content, else its suffix
    (:func:`infer_format`).
    units (mm, cm, m, in): the subject sheet's, applied only when the file does not state its
    own. Labels "Subject:Marker" lose their prefix; a file with several subjects needs
    ``subject_prefix`` (see :mod:`facemotion.io.prefixes`). Missing samples are NaN.
    rate (Hz): the declared frame rate; it replaces the rate an OpenFace CSV's timestamps
    imply, and must equal the rate any other file states.
    """
    from facemotion.io.prefixes import select_subject

    form = get_format(infer_format(path) if fmt is None else fmt, str(path))
    return select_subject(form.read(path, units=units, rate=rate), subject_prefix)


def read_labels(path, fmt: str | None, subject_prefix: str | None = None) -> list[str]:
    """The marker labels of a file, reading no more of it than needed (TRC and CSV: the
    header; C3D and the other exports: the whole file), without a subject prefix."""
    from facemotion.io.prefixes import subject_columns

    labels = get_format(infer_format(path) if fmt is None else fmt, str(path)).labels(path)
    return subject_columns(labels, subject_prefix, str(path))[1]


def write_recording(path, rec: Recording, fmt: str | None = None) -> None:
    """Write ``rec`` in ``fmt`` (default: from the suffix of ``path``)."""
    get_format(infer_format(path) if fmt is None else fmt, str(path)).write(path, rec)
