"""Every reader fuzzed on every shared real file: mutated copies never give a traceback, a
refusal is one line naming the file and showing nothing of it beyond a short token, and a
*structural* mutation that is accepted leaves the values read equal, or is reported.

Structural mutations (the file's shape, which its own redundancy can reveal): truncation; a
line deleted, inserted, duplicated or swapped; a field deleted or inserted; a number of the
header (counts, rate) or its units text changed; bytes of a C3D header or parameter section
flipped. "Reported" means a warning in the ``facemotion`` log (or a refusal).

Value mutations (a digit of a data line, a bit of C3D data) change a value with nothing in the
file to tell: they are held only to the plausibility checks (no traceback; a refusal is one
clear line); the values may differ. A changed C3D label text is such a value change too
(and with it the points kept, since POINT:ANGLES, POWERS, ... name the non-markers by label).

The CI run is seeded and short (``MUTATIONS`` per file and kind); ``pytest -m fuzz_long``
runs many more (deselected by default, tests/conftest.py).
"""

from __future__ import annotations

import logging
import os
import re
import tempfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import FacemotionError

MUTATIONS = 3       # per file and kind in CI
LONG_MUTATIONS = 60  # with -m fuzz_long
LEAK = 24           # a refusal quoting this many characters of the file shows its content

#: (folder under the shared data, glob, reader format)
SOURCES = [
    ("animface", "*.c3d", "c3d"), ("c3d_suite", "*.c3d", "c3d"), ("grid", "*.trc", "trc"),
    ("vendor_suite/c3d", "*.c3d", "c3d"), ("vendor_suite/trc", "*.trc", "trc"),
    ("vendor_suite/openface_csv", "*.csv", "openface_csv"),
    ("vendor_suite/optitrack_csv", "*.csv", "optitrack_csv"),
    ("vendor_suite/qualisys_tsv", "*.tsv", "qualisys_tsv"),
    ("vendor_suite/textgrid", "*.TextGrid", "textgrid"),
]
TEXT_KINDS = ["truncate", "delete_line", "insert_line", "duplicate_line", "swap_lines",
              "delete_field", "insert_field", "header_number", "units_text", "value_digit"]
C3D_KINDS = ["truncate", "header_bits", "parameter_bits", "data_bits"]
VALUE_KINDS = {"value_digit", "data_bits"}

#: Known failures, (format, kind) -> reason, each marked xfail (not pass) until it is fixed.
KNOWN: dict[tuple[str, str], str] = {}   # none left: every finding so far is fixed


#: The wide CSV format has no shared file: it is fuzzed on a shared take written as CSV.
CSV_FROM = SHARED_DATA / "animface" / "animface_jaw.c3d"
CSV_PATH = Path(tempfile.gettempdir()) / f"facemotion-fuzz-{os.getuid()}" / "animface_jaw.csv"


def shared_files() -> list[tuple[Path, str]]:
    out = []
    for folder, pattern, fmt in SOURCES:
        out += [(p, fmt) for p in sorted((SHARED_DATA / folder).glob(pattern))]
    return out + [(CSV_PATH, "csv")]


def _ensure(path: Path) -> None:
    """The CSV copy of a shared take, written once (the reader's writer, then fuzzed)."""
    if path == CSV_PATH and not path.is_file():
        from facemotion.io.c3d import read_c3d
        from facemotion.io.wide_csv import write_csv

        path.parent.mkdir(parents=True, exist_ok=True)
        write_csv(path, read_c3d(CSV_FROM))  # atomic: parallel workers see it whole


FILES = shared_files()


# ----------------------------------------------------------------------------- reading

@dataclass
class Outcome:
    kind: str             # "values", "refused" or "crashed"
    values: object = None
    message: str = ""
    warnings: tuple = ()


class _Warnings(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.records: list[str] = []

    def emit(self, record):
        self.records.append(record.getMessage())


def read(path: Path, fmt: str, tier_names=None) -> Outcome:
    """Read ``path`` as ``fmt``: its values, or its one-line refusal, or the crash."""
    from facemotion.io.registry import read_recording

    log = logging.getLogger("facemotion")
    handler = _Warnings()
    log.addHandler(handler)
    try:
        if fmt == "textgrid":
            from facemotion.ingest.segments import read_textgrid_tier

            values = {n: read_textgrid_tier(path, n) for n in tier_names}
        else:
            rec = read_recording(path, fmt)
            values = (list(rec.labels), float(rec.rate), rec.units,
                      np.asarray(rec.points, dtype=float))
        return Outcome("values", values, warnings=tuple(handler.records))
    except FacemotionError as e:
        return Outcome("refused", message=str(e), warnings=tuple(handler.records))
    except Exception as e:  # noqa: BLE001 (any other exception is the failure looked for)
        return Outcome("crashed", message=f"{type(e).__name__}: {e}")
    finally:
        log.removeHandler(handler)


def same(a, b) -> bool:
    if isinstance(a, dict):
        return a == b
    la, ra, ua, pa = a
    lb, rb, ub, pb = b
    return la == lb and ra == rb and ua == ub and pa.shape == pb.shape and \
        np.array_equal(pa, pb, equal_nan=True)


def difference(a, b) -> str:
    """What differs between two readings (for the failure message)."""
    if isinstance(a, dict):
        return "intervals"
    names = ("labels", "rate", "units", "points")
    return ", ".join(n for n, x, y in zip(names, a, b, strict=True)
                     if not (x.shape == y.shape and np.array_equal(x, y, equal_nan=True)
                             if n == "points" else x == y)) or "nothing"


def labels_differ(a, b) -> bool:
    """Other label texts (with them, possibly other points kept: POINT:ANGLES, POWERS, ...
    name the points that are not markers by label)."""
    return not isinstance(a, dict) and a[0] != b[0]


def units_reported(a, b) -> bool:
    """Other units read from the file: the reading says so (Recording.units, which the study
    writes in sentences.tsv and judges by its face-spread check)."""
    return not isinstance(a, dict) and a[2] != b[2]


_BASELINES: dict[Path, tuple[Outcome, list]] = {}


def baseline(path: Path, fmt: str) -> tuple[Outcome, list]:
    if path not in _BASELINES:
        tiers = []
        if fmt == "textgrid":
            text = path.read_bytes().decode("utf-8", "replace")
            tiers = re.findall(r'class = "IntervalTier"\s*\n\s*name = "([^"]*)"', text) or \
                re.findall(r'"IntervalTier"\s*\n"([^"]*)"', text)
        _BASELINES[path] = (read(path, fmt, tiers), tiers)
    return _BASELINES[path]


# ----------------------------------------------------------------------------- mutations

def _line_index(rng, lines, header=True) -> int:
    n = len(lines)
    if header and rng.random() < 0.5:
        return int(rng.integers(0, min(n, 12)))
    return int(rng.integers(0, n))


def _split_fields(line: bytes) -> tuple[bytes, list[bytes]]:
    for sep in (b"\t", b",", b" "):
        if sep in line:
            return sep, line.split(sep)
    return b"", [line]


#: a number that is a whole field (not a digit inside a label such as L006)
_NUMBER = re.compile(rb"(?<![\w.])-?\d+(\.\d+)?(?![\w.])")


def header_lines(lines: list[bytes]) -> int:
    """Lines before the first data line (one of three or more fields, mostly numbers)."""
    for i, line in enumerate(lines):
        _, fields = _split_fields(line.strip())
        numeric = sum(bool(re.fullmatch(rb"-?[\d.eE+-]+", f.strip())) for f in fields)
        if len(fields) >= 3 and numeric >= 0.8 * len(fields):
            return i
    return min(len(lines), 12)


DID = [""]  # what the last mutation did, for a failure's message


def mutate_text(data: bytes, kind: str, rng) -> bytes | None:
    out = _mutate_text(data, kind, rng)
    if out is not None:
        a, b = data.split(b"\n"), out.split(b"\n")
        common = min(len(a), len(b))
        k = next((i for i in range(common) if a[i] != b[i]), common)
        DID[0] = (f"line {k + 1}: {a[k][:60]!r} -> {b[k][:60]!r}" if k < common
                  else f"{len(a)} -> {len(b)} lines")
    return out


def _mutate_text(data: bytes, kind: str, rng) -> bytes | None:
    lines = data.split(b"\n")
    if kind == "truncate":
        return data[:int(rng.integers(0, len(data)))]
    if len(lines) < 2:
        return None
    i = _line_index(rng, lines)
    if kind == "delete_line":
        del lines[i]
    elif kind == "insert_line":
        lines.insert(i, lines[int(rng.integers(0, len(lines)))])
    elif kind == "duplicate_line":
        lines.insert(i, lines[i])
    elif kind == "swap_lines":
        j = _line_index(rng, lines)
        if lines[i] == lines[j]:
            return None
        lines[i], lines[j] = lines[j], lines[i]
    elif kind in ("delete_field", "insert_field"):
        sep, fields = _split_fields(lines[i])
        if not sep:
            return None
        k = int(rng.integers(0, len(fields)))
        if kind == "delete_field":
            del fields[k]
        else:
            fields.insert(k, fields[k])
        lines[i] = sep.join(fields)
    elif kind == "header_number":
        head = header_lines(lines)
        if head == 0:
            return None
        i = int(rng.integers(0, head))
        found = list(_NUMBER.finditer(lines[i]))
        if not found:
            return None
        m = found[int(rng.integers(0, len(found)))]
        value = float(m.group())
        new = rng.choice([0, -1, value + 1, value * 2, value / 2, 1e9])
        lines[i] = lines[i][:m.start()] + f"{new:g}".encode() + lines[i][m.end():]
    elif kind == "units_text":
        n_head = header_lines(lines)
        head = b"\n".join(lines[:n_head])
        units = [u for u in (b"mm", b"cm", b"Millimeters", b"m\t", b"m\r", b"m\n")
                 if u in head]
        if not units:
            return None
        old = units[int(rng.integers(0, len(units)))]
        repl = rng.choice([b"m", b"cm", b"in", b"xx", b""]) + old[-1:] * (old[-1:] in b"\t\r\n")
        return head.replace(old, repl, 1) + b"\n" + b"\n".join(lines[n_head:])
    elif kind == "value_digit":
        i = int(rng.integers(min(len(lines) - 1, 12), len(lines)))
        digits = [k for k, c in enumerate(lines[i]) if 48 <= c <= 57]
        if not digits:
            return None
        k = digits[int(rng.integers(0, len(digits)))]
        line = bytearray(lines[i])
        line[k] = 48 + (line[k] - 48 + int(rng.integers(1, 10))) % 10
        lines[i] = bytes(line)
    return b"\n".join(lines)


def mutate_c3d(data: bytes, kind: str, rng) -> bytes | None:
    param_start = (data[0] - 1) * 512
    data_start = (int.from_bytes(data[16:18], "little") - 1) * 512
    if not 512 <= param_start < data_start < len(data):
        data_start = param_start + 512 * max(data[param_start + 2], 1)
    if kind == "truncate":
        return data[:int(rng.integers(0, len(data)))]
    lo, hi = {"header_bits": (0, 512), "parameter_bits": (param_start, data_start),
              "data_bits": (data_start, len(data))}[kind]
    if hi <= lo:
        return None
    out = bytearray(data)
    flipped = []
    for _ in range(int(rng.integers(1, 4))):
        k = int(rng.integers(lo, hi))
        out[k] ^= 1 << int(rng.integers(0, 8))
        flipped.append(k)
    DID[0] = f"bytes {flipped} flipped"
    return bytes(out)


# ----------------------------------------------------------------------------- the property

def leaked(message: str, data: bytes, path: Path) -> str | None:
    """A run of LEAK characters of the file's text quoted in ``message`` (outside its path)."""
    text = message.replace(str(path), "")
    content = data.decode("latin-1")
    for i in range(0, max(len(text) - LEAK + 1, 0)):
        run = text[i:i + LEAK]
        if run.strip() and run in content:
            return run
    return None


def check(path: Path, fmt: str, kind: str, n: int, tmp_path: Path) -> list[str]:
    """Problems found in ``n`` mutations of ``path`` of this kind (empty: none)."""
    _ensure(path)
    base, tiers = baseline(path, fmt)
    assert base.kind != "crashed", f"{path}: the unmutated file crashes: {base.message}"
    seed = zlib.crc32(f"{path.name}:{kind}".encode())
    rng = np.random.default_rng(seed)
    data = path.read_bytes()
    problems = []
    for trial in range(n):
        mutated = (mutate_c3d if fmt == "c3d" else mutate_text)(data, kind, rng)
        if mutated is None or mutated == data:
            continue
        target = tmp_path / f"m{trial}{path.suffix}"
        target.write_bytes(mutated)
        got = read(target, fmt, tiers)
        where = f"{path.name} {kind} #{trial} (seed {seed})"
        if got.kind == "crashed":
            problems.append(f"{where}: traceback: {got.message[:300]}")
        elif got.kind == "refused":
            msg = got.message
            if "\n" in msg.strip() or not msg.strip():
                problems.append(f"{where}: refusal is not one line: {msg[:300]!r}")
            elif target.name not in msg:
                problems.append(f"{where}: refusal does not name the file: {msg[:300]}")
            elif leaked(msg, mutated, target):
                problems.append(f"{where}: refusal shows the file's content: {msg[:300]}")
        elif kind not in VALUE_KINDS and base.kind == "values" and not got.warnings \
                and not same(got.values, base.values) \
                and not (fmt == "c3d" and labels_differ(got.values, base.values)) \
                and not units_reported(got.values, base.values):
            problems.append(f"{where}: accepted with other values and nothing reported "
                            f"({difference(got.values, base.values)} differ; {DID[0]})")
    return problems


def _cases(n):
    out = []
    for path, fmt in FILES:
        for kind in (C3D_KINDS if fmt == "c3d" else TEXT_KINDS):
            marks = []
            if (fmt, kind) in KNOWN:
                marks.append(pytest.mark.xfail(reason=KNOWN[(fmt, kind)], strict=False))
            out.append(pytest.param(path, fmt, kind, n, marks=marks,
                                    id=f"{'derived' if path == CSV_PATH else path.parent.name}"
                                       f"/{path.name}-{kind}"))
    return out


def test_every_format_of_the_shared_data_is_fuzzed():
    from facemotion.io.registry import FORMAT_NAMES

    assert {fmt for _, fmt in FILES} == set(FORMAT_NAMES) | {"textgrid"}
    assert len(FILES) >= 25


@pytest.mark.parametrize("path, fmt, kind, n", _cases(MUTATIONS))
def test_mutated_shared_files(path, fmt, kind, n, tmp_path):
    problems = check(path, fmt, kind, n, tmp_path)
    assert problems == [], "\n".join(problems)


@pytest.mark.fuzz_long
@pytest.mark.parametrize("path, fmt, kind, n", _cases(LONG_MUTATIONS))
def test_mutated_shared_files_long(path, fmt, kind, n, tmp_path):
    problems = check(path, fmt, kind, n, tmp_path)
    assert problems == [], "\n".join(problems)
