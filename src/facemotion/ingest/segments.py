"""Cutting long takes into sentences: the subject sheet's ``segments`` column.

A lab records one long take per block and marks the sentences in it. The ``segments`` cell of a
subject says where the marks are, as one of

- ``textgrid:<path>#<tier>``: a Praat TextGrid; every non-empty interval of the interval tier
  ``<tier>`` is a sentence, named by its text;
- ``events:<start label>,<end label>``: pairs of C3D events (EVENT:LABELS / EVENT:TIMES) in each
  take, a sentence from each start event to the next end event, named ``<stem>_01``, ...;
- ``tsv:<path>``: a tab-separated table with columns ``take`` (the take's file stem or name),
  ``start_s``, ``end_s`` and ``name``.

A path may hold ``{stem}`` (the take's file stem) and ``{shared_data}``, and is relative to the
sheet. Time 0 is a take's first sample: sample ``i`` is at ``t = i / rate`` and belongs to the
sentence whose interval ``[start, end)`` holds ``t``; samples outside every interval are not
analysed. A subject's sentences are its takes in the sheet's order, and within a take the
intervals in time order; the count is known when the sheet is read, so datasets can select
training and held-out sentences by number.
"""

from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError, MissingFileError, exception_detail, token
from facemotion.io.recording import Recording

KINDS = ("textgrid", "events", "tsv")
TSV_COLUMNS = ("take", "start_s", "end_s", "name")
# C3D stores event times as 32-bit floats (EVENT:TIMES): a time within this fraction of a frame
# of a sample's time is that sample's time, so that an event placed on frame k starts at k.
EVENT_SNAP_FRAMES = 0.01


@dataclass(frozen=True)
class Segment:
    """One sentence: an interval ``[start_s, end_s)`` of a take (None, None = the whole take)."""

    name: str
    take: str
    start_s: float | None = None
    end_s: float | None = None
    grid_end_s: float | None = None  # the end (xmax) of the TextGrid that cut it, if any

    @property
    def whole(self) -> bool:
        return self.start_s is None

    def to_param(self) -> dict:
        """A plain dict (for rule params and provenance)."""
        out = {"name": self.name, "take": self.take, "start_s": self.start_s,
               "end_s": self.end_s}
        if self.grid_end_s is not None:
            out["grid_end_s"] = self.grid_end_s
        return out

    @classmethod
    def from_param(cls, value) -> Segment:
        if isinstance(value, Segment):
            return value
        if isinstance(value, (str, Path)):
            return cls(Path(value).stem, str(value))
        return cls(str(value["name"]), str(value["take"]), value.get("start_s"),
                   value.get("end_s"), value.get("grid_end_s"))


@dataclass(frozen=True)
class SegmentSpec:
    kind: str
    path: str | None = None
    tier: str | None = None
    start_label: str | None = None
    end_label: str | None = None


def parse_spec(cell: str, where: str) -> SegmentSpec:
    """The ``segments`` cell -> what to read (no file is opened here)."""
    kind, sep, rest = str(cell).strip().partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in KINDS:
        raise InputError(f"{where}: segments {cell!r} must start with textgrid:, events: or tsv:")
    rest = rest.strip()
    if kind == "textgrid":
        path, sep, tier = rest.rpartition("#")
        if not sep or not path.strip() or not tier.strip():
            raise InputError(f"{where}: segments {cell!r} must look like "
                             "'textgrid:<path>#<tier name>'")
        return SegmentSpec("textgrid", path=path.strip(), tier=tier.strip())
    if kind == "events":
        labels = [x.strip() for x in rest.split(",")]
        if len(labels) != 2 or not all(labels):
            raise InputError(f"{where}: segments {cell!r} must look like "
                             "'events:<start label>,<end label>'")
        return SegmentSpec("events", start_label=labels[0], end_label=labels[1])
    if not rest:
        raise InputError(f"{where}: segments {cell!r} must look like 'tsv:<path>'")
    return SegmentSpec("tsv", path=rest)


def _resolve(template: str, take: str, sheet_dir: Path, shared_data) -> Path:
    text = template.replace("{stem}", Path(take).stem)
    if "{shared_data}" in text:
        if shared_data is None:
            raise InputError(f"shared_data: the segments path {template!r} uses "
                             "{shared_data}, and no shared_data folder is given")
        text = text.replace("{shared_data}", str(shared_data))
    p = Path(text)
    return p if p.is_absolute() else sheet_dir / p


def _clean_name(text) -> str:
    return " ".join(str(text).split())


def check_intervals(intervals: list[tuple[float, float]], where: str) -> None:
    """Each interval finite with 0 <= start < end; sorted by start, none overlaps the next."""
    for s, e in intervals:
        if not (math.isfinite(s) and math.isfinite(e)):
            raise InputError(f"{where}: interval {s!r}-{e!r} s is not finite")
        if s < 0:
            raise InputError(f"{where}: interval {s:.6g}-{e:.6g} s starts before the take "
                             "(negative time)")
        if not s < e:
            raise InputError(f"{where}: interval {s:.6g}-{e:.6g} s is empty or runs backwards")
    ordered = sorted(intervals)
    for (s0, e0), (s1, e1) in zip(ordered, ordered[1:], strict=False):
        if s1 < e0:
            raise InputError(f"{where}: intervals {s0:.6g}-{e0:.6g} s and {s1:.6g}-{e1:.6g} s "
                             "overlap")


def check_within_take(intervals, n_frames: int, rate: float, where: str) -> None:
    """Every interval ends at or before the end of the take, ``n_frames / rate``."""
    duration = n_frames / rate
    for s, e in intervals:
        if e > duration:
            raise InputError(f"{where}: interval {s:.6g}-{e:.6g} s ends beyond the take "
                             f"({n_frames} frames at {rate:g} Hz = {duration:.6g} s)")


# ------------------------------------------------------------------------------- TextGrid

def check_grid_fits_take(grid_end_s: float, n_frames: int, rate: float, where: str) -> None:
    """A TextGrid may end up to one frame after its take (the sound's and the take's ends are
    quantised differently); one longer than that belongs to another, longer recording."""
    duration = n_frames / rate
    if grid_end_s > duration + 1.0 / rate:
        raise InputError(f"{where}: the TextGrid runs to {grid_end_s:.6g} s, longer than its "
                         f"take ({n_frames} frames at {rate:g} Hz = {duration:.6g} s): it "
                         "belongs to another recording, or the take is cut short")


@dataclass(frozen=True)
class TextGridTiers:
    """A TextGrid as read: its time domain and tiers (name -> (is an interval tier, entries
    (start, end, text); a point tier's entries have start == end))."""

    xmin: float
    xmax: float
    tiers: dict[str, tuple[bool, list[tuple[float, float, str]]]]
    reader: str   # "praatio" or "praat" (parselmouth)


def read_textgrid(path) -> TextGridTiers:
    """A Praat TextGrid through praatio, or through Praat itself (parselmouth) for what
    praatio cannot read: the binary and chronological formats, ``!`` comments, short text
    without the blank line, scientific-notation times. The text's encoding is detected
    (:func:`textgrid_text`)."""
    p = Path(path)
    if not p.is_file():
        raise MissingFileError(f"{p}: TextGrid file not found")
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise InputError(f"{p}: cannot read the TextGrid ({type(e).__name__})") from None
    text = None if raw.startswith(b"ooBinaryFile") else textgrid_text(raw)
    if text is not None and '"TextGrid"' in _short_tokens(text)[:8] and \
            "chronological" not in text.splitlines()[0]:
        long_format = re.search(r"^\s*xmin\s*=", text, re.M) is not None
        try:
            _check_long_format(text) if long_format else _check_short_format(text)
        except ValueError as e:
            raise InputError(f"{p}: not a consistent TextGrid ({e})") from None
    if text is not None:
        try:
            return _praatio_tiers(text)
        except Exception:  # praatio raises several kinds on what it does not parse
            pass  # Praat's own parser reads it or says why not
    tg = _praat_tiers(p)
    _check_structure(tg, None if text is None else _declared_sizes(text), p)
    return tg


def _check_structure(tg: TextGridTiers, sizes: list[int] | None, p: Path) -> None:
    """Praat reads the long format by its numbers and texts in order, so a repeated or
    inserted line can shift what follows into other intervals: the declared sizes and the
    tiling of the interval tiers must still hold."""
    for i, (interval, entries) in enumerate(tg.tiers.values()):
        try:
            if sizes is not None and (i >= len(sizes) or sizes[i] != len(entries)):
                raise ValueError(f"tier {i + 1} declares "
                                 f"{sizes[i] if i < len(sizes) else 'no'} entries and holds "
                                 f"{len(entries)}")
            if interval and entries:  # a tier's own domain may lie inside the grid's
                _check_tiling(entries, entries[0][0], entries[-1][1], i + 1)
                if entries[0][0] < tg.xmin or entries[-1][1] > tg.xmax:
                    raise ValueError(f"interval tier {i + 1} runs outside the TextGrid")
        except ValueError as e:
            raise InputError(f"{p}: not a consistent TextGrid ({e})") from None


def textgrid_text(raw: bytes) -> str | None:
    """A text TextGrid's characters: UTF-8 or UTF-16 by their byte-order mark, UTF-16 without
    one by its NUL bytes, else UTF-8, else Latin-1 (Praat's older default); None for a file
    that is not text in any of them."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        encoding = "utf-16"
    elif raw.startswith(b"\xef\xbb\xbf"):
        encoding = "utf-8-sig"
    elif len(raw) >= 4 and raw[1] == 0 and raw[3] == 0 and raw[0] != 0:
        encoding = "utf-16-le"
    elif len(raw) >= 4 and raw[0] == 0 and raw[2] == 0 and raw[1] != 0:
        encoding = "utf-16-be"
    else:
        encoding = "utf-8"
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError:
        if encoding != "utf-8" or b"\x00" in raw:
            return None
        return raw.decode("latin-1")


def _praatio_tiers(text: str) -> TextGridTiers:
    from praatio.utilities import textgrid_io

    tg = textgrid_io.parseTextgridStr(text, includeEmptyIntervals=True)
    tiers = {}
    sizes = _declared_sizes(text)
    for i, t in enumerate(tg["tiers"]):
        interval = t["class"] == "IntervalTier"
        entries = [(float(e[0]), float(e[1]) if interval else float(e[0]), str(e[-1]))
                   for e in t["entries"]]
        if sizes is not None and (i >= len(sizes) or sizes[i] != len(entries)):
            raise ValueError(f"tier {i + 1} declares {sizes[i] if i < len(sizes) else 'no'} "
                             f"entries and holds {len(entries)}")
        if interval:
            _check_tiling(entries, float(t["xmin"]), float(t["xmax"]), i + 1)
        tiers.setdefault(str(t["name"]), (interval, entries))
    return TextGridTiers(float(tg["xmin"]), float(tg["xmax"]), tiers, "praatio")


_LONG_KEYS = ("File type", "Object class", "xmin", "xmax", "tiers?", "size", "item [",
              "item []", "class", "name", "intervals", "points", "number", "mark", "text")


def _check_long_format(text: str) -> None:
    """The long text format writes one ``key = value`` (or ``item [i]:``) per line and each
    interval's xmin, xmax and text once: a line that is none of these, or an interval whose
    keys are repeated or missing, is a damaged file (Praat and praatio would read the values
    around it as other intervals)."""
    inside, block = False, None
    for n, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if inside:  # a text that runs over several lines
            inside = stripped.count('"') % 2 == 0
            continue
        if '"' not in stripped:  # Praat's comments run from '!' to the line's end
            stripped = stripped.split("!", 1)[0].strip()
        if not stripped:
            continue
        if not stripped.startswith(_LONG_KEYS):
            raise ValueError(f"line {n}: not a line of the long text format")
        inside = stripped.count('"') % 2 == 1
        key = re.split(r"[\s=\[:]", stripped, maxsplit=1)[0]
        if key in ("intervals", "points") and "[" in stripped:
            block = []
        elif block is not None and key in ("xmin", "xmax", "text", "number", "mark"):
            if key in block:
                raise ValueError(f"line {n}: {key} repeated in one interval or point")
            block.append(key)
        elif key == "item":
            block = None


def _short_tokens(text: str) -> list[str]:
    """The short text format's tokens: quoted texts (which may hold doubled quotes and line
    ends) and bare words or numbers, without '!' comments."""
    return re.findall(r'"(?:[^"]|"")*"|[^\s"!]+|!.*', text)


def _check_short_format(text: str) -> None:
    """The short text format is a fixed sequence of numbers and quoted texts: per interval
    tier its class, name, xmin, xmax and count, then per interval two numbers and a text (a
    point tier: a number and a text). A line inserted, repeated or lost shifts the sequence;
    Praat and praatio may still read it, as other intervals."""
    toks = [t for t in _short_tokens(text) if not t.startswith("!")]

    def num(i):
        try:
            float(toks[i])
        except (IndexError, ValueError):
            raise ValueError(f"token {i + 1}: expected a number") from None

    def txt(i):
        if i >= len(toks) or not toks[i].startswith('"'):
            raise ValueError(f"token {i + 1}: expected a quoted text")

    # the header: File type = "ooTextFile" Object class = "TextGrid"
    if '"TextGrid"' not in toks[:8]:
        raise ValueError("no 'Object class = \"TextGrid\"' header")
    i = toks.index('"TextGrid"') + 1
    num(i), num(i + 1)
    if toks[i + 2] != "<exists>":
        raise ValueError(f"token {i + 3}: expected <exists>")
    num(i + 3)
    n_tiers, i = int(float(toks[i + 3])), i + 4
    for _ in range(n_tiers):
        txt(i), txt(i + 1), num(i + 2), num(i + 3), num(i + 4)
        kind, n, i = toks[i], int(float(toks[i + 4])), i + 5
        width = 3 if kind == '"IntervalTier"' else 2
        for _ in range(n):
            for j in range(width - 1):
                num(i + j)
            txt(i + width - 1)
            i += width
    if i != len(toks):
        raise ValueError(f"{len(toks) - i} token(s) after the last tier")


def _declared_sizes(text: str) -> list[int] | None:
    """The long text format's ``intervals: size = N`` / ``points: size = N`` of each tier, in
    order (None for the short format, which declares them as bare numbers)."""
    found = re.findall(r"^\s*(?:intervals|points):\s*size\s*=\s*(\d+)", text, re.M)
    return [int(n) for n in found] if "item [" in text else None


def _check_tiling(entries, xmin: float, xmax: float, tier: int) -> None:
    """An interval tier tiles its time domain: each interval starts where the one before it
    ends, the first at the tier's xmin, the last ending at its xmax (Praat writes it so); a
    file cut or edited by hand breaks the chain."""
    tol = 1e-9 * max(1.0, abs(xmax))
    edges = [xmin] + [e for _, e, _ in entries]
    starts = [s for s, _, _ in entries]
    if not entries or any(abs(a - b) > tol for a, b in zip(starts, edges, strict=False)) \
            or abs(edges[-1] - xmax) > tol or any(e <= s for s, e, _ in entries):
        raise ValueError(f"interval tier {tier}: its intervals do not tile {xmin:g}-{xmax:g} s")


def _praat_tiers(p: Path) -> TextGridTiers:
    """The TextGrid read by Praat (parselmouth), tier by tier through Praat's own queries."""
    import parselmouth
    from parselmouth.praat import call

    try:
        tg = parselmouth.read(str(p))
        if not isinstance(tg, parselmouth.TextGrid):
            raise InputError(f"{p}: a Praat {type(tg).__name__}, not a TextGrid")
        tiers = {}
        for i in range(1, call(tg, "Get number of tiers") + 1):
            name = call(tg, "Get tier name...", i)
            if call(tg, "Is interval tier...", i):
                entries = [(call(tg, "Get start time of interval...", i, k),
                            call(tg, "Get end time of interval...", i, k),
                            call(tg, "Get label of interval...", i, k))
                           for k in range(1, call(tg, "Get number of intervals...", i) + 1)]
            else:
                entries = [(t, t, call(tg, "Get label of point...", i, k))
                           for k in range(1, call(tg, "Get number of points...", i) + 1)
                           for t in [call(tg, "Get time of point...", i, k)]]
            tiers.setdefault(str(name), (bool(call(tg, "Is interval tier...", i)), entries))
        return TextGridTiers(call(tg, "Get start time"), call(tg, "Get end time"), tiers,
                             "praat")
    except parselmouth.PraatError as e:  # its quotes may hold the file's bytes: tokens only
        raise InputError(f"{p}: cannot read as a Praat TextGrid (Praat: "
                         f"{exception_detail(e)})") from None


def read_textgrid_tier(path, tier: str) -> list[tuple[float, float, str]]:
    """The non-empty intervals ``(start, end, text)`` of an interval tier."""
    return read_textgrid_intervals(path, tier)[0]


def read_textgrid_intervals(path, tier: str) -> tuple[list[tuple[float, float, str]], float]:
    """The non-empty intervals ``(start, end, text)`` of an interval tier, and the TextGrid's
    end (xmax): the take it cuts must be at least that long. A TextGrid must start at 0 (the
    take's first sample); one whose xmin is not 0 holds another time line (a part extracted
    with its original times) and is refused."""
    p = Path(path)
    tg = read_textgrid(p)
    if tg.xmin != 0:
        raise InputError(f"{p}: the TextGrid starts at {tg.xmin:.6g} s, not 0: its times are "
                         "not the take's (a part extracted with its original times?); shift "
                         "it to start at 0 (Praat: Modify times, Shift times to)")
    if tier not in tg.tiers:
        tiers = ", ".join(token(t) for t in list(tg.tiers)[:10]) or "none"
        raise InputError(f"{p}: no tier {tier!r} (tiers: {tiers})")
    interval, entries = tg.tiers[tier]
    if not interval:
        raise InputError(f"{p}: tier {tier!r} is a point tier; sentences need an interval tier")
    out = [(float(s), float(e), _clean_name(label)) for s, e, label in entries
           if str(label).strip()]
    if not out:
        raise InputError(f"{p}: tier {tier!r} has no non-empty interval")
    for s, e, _ in out:
        if s < tg.xmin or e > tg.xmax:
            raise InputError(f"{p}: tier {tier!r} interval {s:.6g}-{e:.6g} s lies outside the "
                             f"TextGrid's {tg.xmin:.6g}-{tg.xmax:.6g} s")
    return out, float(tg.xmax)


# ------------------------------------------------------------------------------- C3D events

@dataclass(frozen=True)
class TakeEvents:
    events: list[tuple[str, float]]   # (label, time in s from the take's first sample)
    rate: float
    n_frames: int


def read_c3d_events(path, subject_prefix: str | None = None) -> TakeEvents:
    """A C3D take's EVENT group: labels and times from the take's first sample.

    EVENT:TIMES count from frame 1 of the capture (minutes and seconds, added); in a trial
    that starts later (header first frame f > 1) they are shifted by (f - 1) / rate. TIMES is
    a 2 x N array (minutes row, seconds row), or, as some Vicon/BTK files store it, one flat
    list of 2N values, minutes and seconds interleaved (:func:`event_times`). Times within
    ``EVENT_SNAP_FRAMES`` of a sample are snapped to it (they are stored as 32-bit floats). An
    event outside the take (before its first sample or after its end) is an error naming it.
    With ``subject_prefix``, events of other subjects (EVENT:SUBJECTS) are ignored.
    """
    from facemotion.io.c3d import check_c3d_size, open_c3d

    p = Path(path)
    if not p.is_file():
        raise MissingFileError(f"{p}: file not found")
    check_c3d_size(p)  # a damaged parameter section can crash ezc3d
    c = open_c3d(p)
    point = c["parameters"]["POINT"]
    rate_v = np.ravel(point["RATE"]["value"]) if "RATE" in point else np.array([])
    rate = float(rate_v[0]) if rate_v.size else float(c["header"]["points"]["frame_rate"])
    if not math.isfinite(rate) or rate <= 0:
        raise InputError(f"{p}: POINT:RATE must be positive, got {rate}")
    n_frames = int(np.shape(c["data"]["points"])[2])
    first = int(c["header"]["points"]["first_frame"])  # 0-based: header word 4 minus 1
    group = c["parameters"].get("EVENT", {})
    used = int(np.ravel(group["USED"]["value"])[0]) if "USED" in group else 0
    if used == 0:
        raise InputError(f"{p}: no events (the C3D EVENT group is missing or empty)")
    labels = [str(x).strip() for x in group["LABELS"]["value"]] if "LABELS" in group else []
    if len(labels) < used:
        raise InputError(f"{p}: EVENT:USED is {used} but EVENT:LABELS names {len(labels)}")
    minutes, seconds = event_times(group["TIMES"]["value"] if "TIMES" in group else [],
                                   used, str(p))
    subjects = ([str(x).strip() for x in group["SUBJECTS"]["value"]][:used]
                if "SUBJECTS" in group else [""] * used)
    duration = n_frames / rate
    events = []
    for k, (lab, m, sec, subj) in enumerate(zip(labels[:used], minutes, seconds, subjects,
                                                strict=False)):
        if subject_prefix and subj and subj != subject_prefix:
            continue
        t = float(m) * 60.0 + float(sec) - first / rate
        i = round(t * rate)
        if abs(t * rate - i) <= EVENT_SNAP_FRAMES:
            t = i / rate
        if not (math.isfinite(t) and 0 <= t <= duration):
            raise InputError(f"{p}: event {k + 1} {token(lab)} at {t:.4g} s is outside the take "
                             f"(0-{duration:.4g} s: {n_frames} frames at {rate:g} Hz from "
                             f"capture frame {first + 1})")
        events.append((lab, t))
    return TakeEvents(events, rate, n_frames)


def event_times(value, used: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """EVENT:TIMES as (minutes, seconds) of the first ``used`` events, from either layout:
    a 2 x N array, or a flat list of 2N values with minutes and seconds interleaved."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 2 and arr.shape[0] == 2 and arr.shape[1] >= used:
        return arr[0, :used], arr[1, :used]
    if arr.ndim == 1 and arr.size >= 2 * used and arr.size % 2 == 0:
        pairs = arr.reshape(-1, 2)  # (minutes, seconds) per event
        return pairs[:used, 0], pairs[:used, 1]
    raise InputError(f"{where}: EVENT:TIMES has shape {arr.shape}, not 2 x N or 2N values "
                     f"for the {used} events of EVENT:USED")


def pair_events(events: list[tuple[str, float]], start_label: str, end_label: str,
                where: str) -> list[tuple[float, float]]:
    """Intervals from each start event to the next end event; anything unpaired is an error."""
    chosen = [(t, lab) for lab, t in events if lab in (start_label, end_label)]
    if not chosen:
        have = sorted({lab for lab, _ in events})
        listing = ", ".join(token(x) for x in have[:10]) or "none"
        raise InputError(f"{where}: no events labelled {start_label!r} or {end_label!r} "
                         f"(events in the file: {listing})")
    # at equal times an end closes the previous sentence before a start opens the next
    chosen.sort(key=lambda x: (x[0], 0 if x[1] == end_label else 1))
    pairs: list[tuple[float, float]] = []
    open_t: float | None = None
    for t, lab in chosen:
        is_start = lab == start_label if start_label != end_label else open_t is None
        if is_start:
            if open_t is not None:
                raise InputError(f"{where}: unpaired events: {start_label!r} at {open_t:.4f} s "
                                 f"is followed by another {start_label!r} at {t:.4f} s before "
                                 f"an {end_label!r}")
            open_t = t
        else:
            if open_t is None:
                raise InputError(f"{where}: unpaired events: {end_label!r} at {t:.4f} s has no "
                                 f"{start_label!r} before it")
            pairs.append((open_t, t))
            open_t = None
    if open_t is not None:
        raise InputError(f"{where}: unpaired events: {start_label!r} at {open_t:.4f} s has no "
                         f"{end_label!r} after it")
    return pairs


# ------------------------------------------------------------------------------- TSV

def read_interval_table(path) -> list[tuple[int, str, float, float, str]]:
    """Rows ``(line, take, start_s, end_s, name)`` of a segments table."""
    import pandas as pd

    p = Path(path)
    if not p.is_file():
        raise MissingFileError(f"{p}: segments table not found")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: segments table cannot be read as UTF-8 text "
                         f"({type(e).__name__})") from None
    # only whole lines starting with '#' are comments: a '#' inside a name is part of it
    kept = [(n, line) for n, line in enumerate(text.splitlines(), start=1)
            if line.strip() and not line.lstrip().startswith("#")]
    try:
        df = pd.read_csv(io.StringIO("\n".join(line for _, line in kept) + "\n"), sep="\t",
                         dtype=str, keep_default_na=False, quoting=3)  # literal cells
    except Exception as e:
        raise InputError(f"{p}: cannot be parsed as TSV ({type(e).__name__})") from None
    line_of = [n for n, _ in kept[1:]]
    df.columns = [str(c).strip() for c in df.columns]
    missing = [c for c in TSV_COLUMNS if c not in df.columns]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}; expected "
                         f"{', '.join(TSV_COLUMNS)} (tab-separated)")
    if df.empty:
        raise InputError(f"{p}: segments table has no rows")
    rows = []
    for j, r in enumerate(df.itertuples(index=False)):
        i = line_of[j]
        rec = dict(zip(df.columns, r, strict=True))
        vals = []
        for col in ("start_s", "end_s"):
            try:
                vals.append(float(str(rec[col]).strip()))
            except ValueError:
                raise InputError(f"{p}, line {i}: {col} {token(rec[col])} is not a "
                                 "number") from None
        name = _clean_name(rec["name"])
        if not name:
            raise InputError(f"{p}, line {i}: empty name")
        take = str(rec["take"]).strip()
        if not take:
            raise InputError(f"{p}, line {i}: empty take")
        rows.append((i, take, vals[0], vals[1], name))
    return rows


# ------------------------------------------------------------------------------- the sheet

def _unique_names(segments: list[Segment]) -> list[Segment]:
    """A name used more than once gets ' [2]', ' [3]', ... on its later uses, in order."""
    seen: dict[str, int] = {}
    out = []
    for s in segments:
        k = seen.get(s.name, 0) + 1
        seen[s.name] = k
        out.append(s if k == 1 else Segment(f"{s.name} [{k}]", s.take, s.start_s, s.end_s,
                                            s.grid_end_s))
    return out


def segment_subject(cell: str, takes: list[str], fmt: str, sheet_dir, where: str,
                    shared_data=None, subject_prefix: str | None = None
                    ) -> tuple[list[Segment], list[str]]:
    """A subject's sentences from its ``segments`` cell, and the files they were read from.

    Intervals are checked here (finite, non-negative, non-overlapping; for C3D events also
    within the take); that an interval ends within a take of another format is checked when
    the take is read (:func:`frame_range`).
    """
    spec = parse_spec(cell, where)
    sheet_dir = Path(sheet_dir)
    segments: list[Segment] = []
    sources: list[str] = []
    if spec.kind == "textgrid":
        if "{stem}" not in spec.path and len(takes) > 1:
            raise InputError(f"{where}: segments path {spec.path!r} must hold {{stem}} (one "
                             f"TextGrid per take) since the subject has {len(takes)} takes")
        owner: dict[str, str] = {}
        for take in takes:
            path = _resolve(spec.path, take, sheet_dir, shared_data)
            first = owner.setdefault(str(Path(path).resolve()), take)
            if first != take:
                raise InputError(f"{where}: takes {first} and {take} both resolve to the "
                                 f"TextGrid {path}; a TextGrid cuts one take (give the takes "
                                 "different file names)")
            try:
                rows, grid_end = read_textgrid_intervals(path, spec.tier)
                check_intervals([(s, e) for s, e, _ in rows], f"{path} tier {spec.tier!r}")
            except InputError as e:
                raise InputError(f"{where}: {e}") from None
            segments += [Segment(name, take, s, e, grid_end) for s, e, name in sorted(rows)]
            sources.append(str(path))
    elif spec.kind == "events":
        if fmt != "c3d":
            raise InputError(f"{where}: segments 'events:' reads C3D events, but the format is "
                             f"{fmt!r}; use textgrid: or tsv: instead")
        for take in takes:
            try:
                ev = read_c3d_events(take, subject_prefix)
                pairs = pair_events(ev.events, spec.start_label, spec.end_label, str(take))
                check_intervals(pairs, str(take))
                check_within_take(pairs, ev.n_frames, ev.rate, str(take))
            except InputError as e:
                raise InputError(f"{where}: {e}") from None
            stem = Path(take).stem
            segments += [Segment(f"{stem}_{k + 1:02d}", take, s, e)
                         for k, (s, e) in enumerate(sorted(pairs))]
    else:
        segments, sources = _segments_from_tables(spec, takes, sheet_dir, where, shared_data)
    return _unique_names(segments), sources


def _segments_from_tables(spec, takes, sheet_dir, where, shared_data):
    by_key: dict[str, str] = {}
    for take in takes:
        for key in (Path(take).stem, Path(take).name):
            if key in by_key and by_key[key] != take:
                raise InputError(f"{where}: takes {by_key[key]} and {take} share the name "
                                 f"{key!r}; a segments table cannot tell them apart")
            by_key[key] = take
    per_take = "{stem}" in spec.path
    tables = ([(take, _resolve(spec.path, take, sheet_dir, shared_data)) for take in takes]
              if per_take else [(None, _resolve(spec.path, takes[0], sheet_dir, shared_data))])
    rows_of: dict[str, list[tuple[int, float, float, str, Path]]] = {t: [] for t in takes}
    sources = []
    for own_take, path in tables:
        try:
            rows = read_interval_table(path)
        except InputError as e:
            raise InputError(f"{where}: {e}") from None
        sources.append(str(path))
        for line, key, s, e, name in rows:
            take = by_key.get(key)
            if take is None or (own_take is not None and take != own_take):
                have = ", ".join(Path(t).stem for t in takes[:8])
                what = (f"the take of this table is {Path(own_take).stem!r}" if own_take
                        else f"the subject's takes are {have}{', ...' if len(takes) > 8 else ''}")
                raise InputError(f"{where}: {path}, line {line}: take {token(key)} is not a "
                                 f"recording of this subject ({what})")
            rows_of[take].append((line, s, e, name, path))
    segments = []
    for take in takes:
        rows = rows_of[take]
        if not rows:
            raise InputError(f"{where}: segments table(s) {', '.join(sources)} have no row for "
                             f"take {Path(take).stem!r}")
        try:
            check_intervals([(s, e) for _, s, e, _, _ in rows],
                            f"{rows[0][4]} (take {Path(take).stem!r})")
        except InputError as e:
            raise InputError(f"{where}: {e}") from None
        segments += [Segment(name, take, s, e) for _, s, e, name, _ in
                     sorted(rows, key=lambda r: r[1])]
    return segments, sources


# ------------------------------------------------------------------------------- cutting

def first_sample_at_or_after(t: float, rate: float) -> int:
    """The smallest i >= 0 with i / rate >= t (evaluated as the sample times are)."""
    i = max(0, math.ceil(t * rate))
    while i > 0 and (i - 1) / rate >= t:
        i -= 1
    while i / rate < t:
        i += 1
    return i


def frame_range(start_s: float, end_s: float, rate: float, n_frames: int,
                where: str) -> tuple[int, int]:
    """Samples ``i0 .. i1-1`` whose times ``i / rate`` lie in ``[start_s, end_s)``."""
    check_within_take([(start_s, end_s)], n_frames, rate, where)
    i0 = first_sample_at_or_after(start_s, rate)
    i1 = min(first_sample_at_or_after(end_s, rate), n_frames)
    if i1 <= i0:
        raise InputError(f"{where}: interval {start_s:.6g}-{end_s:.6g} s holds no sample at "
                         f"{rate:g} Hz")
    return i0, i1


def cut(rec: Recording, seg: Segment) -> Recording:
    """The part of a take that is the sentence ``seg`` (the whole take when it has no interval)."""
    if seg.whole:
        return rec
    where = f"{rec.source or seg.take} (sentence {seg.name!r})"
    if seg.grid_end_s is not None:
        check_grid_fits_take(seg.grid_end_s, rec.n_frames, rec.rate, where)
    i0, i1 = frame_range(float(seg.start_s), float(seg.end_s), rec.rate, rec.n_frames, where)
    return Recording(rec.labels, rec.points[i0:i1].copy(), rec.rate,
                     source=f"{rec.source or seg.take} [{seg.name}]",
                     filled=rec.filled[i0:i1].copy(), units=rec.units,
                     units_source=rec.units_source)
