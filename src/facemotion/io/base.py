"""What the text readers share: readable files, units, number formatting, and the fast parser
of regular numeric tables."""

from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from facemotion.errors import InputError, MissingFileError, token

#: Parse regular TRC/CSV text with the C parser (benchmarks switch it off to compare).
FAST_TEXT = True


# Millimetres per unit, with the spellings found in C3D/TRC files.
_MM_PER_UNIT = {
    "mm": 1.0, "millimeter": 1.0, "millimeters": 1.0, "millimetre": 1.0, "millimetres": 1.0,
    "cm": 10.0, "centimeter": 10.0, "centimeters": 10.0, "centimetre": 10.0, "centimetres": 10.0,
    "m": 1000.0, "meter": 1000.0, "meters": 1000.0, "metre": 1000.0, "metres": 1000.0,
    "in": 25.4, "inch": 25.4, "inches": 25.4,
}


#: The units a sheet or an argument may name (a file may spell them as in ``_MM_PER_UNIT``).
UNITS = ("mm", "cm", "m", "in")



def head_lines(path, n: int) -> tuple[Path, list[str]]:
    """A readable text file's first ``n`` lines (UTF-8, a BOM dropped); InputError naming
    the file if it cannot be read as text."""
    p = check_readable(path)
    try:
        with open(p, encoding="utf-8-sig") as fh:
            return p, [fh.readline() for _ in range(n)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read as text ({type(e).__name__})") from None

def unit_scale(unit: str, where: str) -> float:
    """Millimetres per ``unit`` (mm, cm, m, in); InputError naming ``where`` otherwise."""
    key = str(unit).strip().lower()
    if key not in _MM_PER_UNIT:
        raise InputError(f"{where}: unknown units {token(unit)} (supported: {', '.join(UNITS)})")
    return _MM_PER_UNIT[key]


def check_readable(path) -> Path:
    p = Path(path)
    if not p.exists():
        raise MissingFileError(f"{p}: file not found")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a recording file")
    if not p.is_file():
        raise InputError(f"{p}: not a regular file")
    if not os.access(p, os.R_OK):
        raise InputError(f"{p}: file is not readable (permission denied)")
    return p


def split_tab_line(line: str) -> list[str]:
    return line.rstrip("\r\n").split("\t")


def check_last_line_ended(path, lines: list[str]) -> None:
    """InputError if the text's last non-blank line has no line end (the file was cut)."""
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].strip(" \r\n"):
            if not lines[i].endswith("\n"):
                raise InputError(f"{path}: line {i + 1}, the last one, has no line end: the "
                                 "file looks cut short")
            return


def is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def format_coordinate(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.6f}"


#: Bytes of text parsed per chunk by the fast path (bounds its temporary memory).
FAST_CHUNK_BYTES = 16 * 2**20


def fast_numeric_lines(path: Path, offset: int, first_line: int, ncol: int, sep: bytes,
                        max_rows: int | None = None, empty_extra: bool = False):
    """Numeric data lines of a text table at C-parser speed, or None to use the exact path.

    Reads from byte ``offset`` (line number ``first_line``) in chunks of whole lines: numpy
    finds each line's end and counts its separators; pandas' C parser (quoting off, only an
    empty field is missing) converts the chunk. Returns (values (lines x ncol) float64, the
    1-based line number of each data line). Returns None whenever the text is not plainly
    regular - a line with another number of fields, a line of spaces, NUL or non-ASCII bytes,
    a last line without a line end, a token the C parser does not take as a number, other
    than ``max_rows`` lines when given - so that the exact line-by-line reader gives the error
    or the reading. Extra fields beyond ``ncol`` are taken only when empty and ``empty_extra``
    (TRC: some writers end lines with a tab; a CSV row must match its header). The values are
    those the exact reader returns (pandas' default float parser: identical on 300,000 random
    values written with 6 decimals, the writers' format).
    """
    out = None if max_rows is None else np.empty((max_rows, ncol))
    blocks, numbers = [], []
    rows = 0
    line_no = first_line
    try:
        for chunk in _whole_line_chunks(path, offset):
            fields, data_lines = _line_fields(chunk, ord(sep), ncol, empty_extra)
            if fields.size:
                vals = _parse_chunk(chunk, sep, int(fields.max()), ncol, fields.size)
                if out is not None:
                    if rows + vals.shape[0] > max_rows:
                        return None
                    out[rows:rows + vals.shape[0]] = vals
                else:
                    blocks.append(np.ascontiguousarray(vals))
                rows += vals.shape[0]
                numbers.append(line_no + np.flatnonzero(data_lines))
            line_no += data_lines.size
    except _Irregular:
        return None
    if rows == 0 or (out is not None and rows != max_rows):
        return None
    if out is not None:
        values = out
    else:
        values = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
    return values, np.concatenate(numbers)


class _Irregular(Exception):
    """The text is not plainly regular: the exact line-by-line reader takes it."""


def _whole_line_chunks(path: Path, offset: int):
    """The file from byte ``offset`` in chunks of about FAST_CHUNK_BYTES ending at a line end."""
    carry = b""
    with open(path, "rb") as fh:
        fh.seek(offset)
        while True:
            data = fh.read(FAST_CHUNK_BYTES)
            buf = carry + data
            if not data:
                if buf.strip(b" \r\n"):
                    raise _Irregular  # last line without a line end: the exact path says so
                return
            cut = buf.rfind(b"\n") + 1
            if cut == 0:
                carry = buf
                continue
            yield buf[:cut]
            carry = buf[cut:]


def _line_fields(chunk: bytes, sep_code: int, ncol: int, empty_extra: bool
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The number of fields of each data line of a chunk, and which of its lines are data
    (not blank); irregular text (NUL, non-ASCII, another field count) raises _Irregular."""
    arr = np.frombuffer(chunk, dtype=np.uint8)
    if arr.max() >= 128 or not arr.all():
        raise _Irregular  # NUL or non-ASCII text: the exact path decodes and judges it
    nl = np.flatnonzero(arr == 10)
    starts = np.concatenate([[0], nl[:-1] + 1])
    length = nl - starts
    cr = np.zeros(nl.size, dtype=bool)
    has = length > 0
    cr[has] = arr[nl[has] - 1] == 13
    length = length - cr
    seps = np.flatnonzero(arr == sep_code)  # separators per line, from positions
    fields = np.diff(np.concatenate([[0], np.searchsorted(seps, nl)])) + 1
    blank = length == 0
    if np.any((fields == 1) & ~blank & (ncol > 1)):
        raise _Irregular  # a line without separators (spaces only, or one field)
    data_lines = ~blank
    f = fields[data_lines]
    if f.size and (f.min() < ncol or (f.max() > ncol and not empty_extra)):
        raise _Irregular
    return f, data_lines


def _parse_chunk(chunk: bytes, sep: bytes, width: int, ncol: int, n_rows: int) -> np.ndarray:
    """The chunk's (n_rows, ncol) values by pandas' C parser (only an empty field missing)."""
    import csv as _csv

    import pandas as pd

    try:
        df = pd.read_csv(io.BytesIO(chunk), sep=sep.decode(), header=None,
                         names=range(width), dtype=np.float64, engine="c",
                         keep_default_na=False, na_values=[""],
                         quoting=_csv.QUOTE_NONE, skip_blank_lines=True)
    except (ValueError, TypeError, pd.errors.ParserError):
        raise _Irregular from None
    vals = df.to_numpy(dtype=np.float64)
    if vals.shape[0] != n_rows:
        raise _Irregular
    if width > ncol:
        if not np.isnan(vals[:, ncol:]).all():
            raise _Irregular  # text beyond the declared fields: the exact path's error
        vals = vals[:, :ncol]
    return vals
