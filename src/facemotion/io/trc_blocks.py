"""TRC files read in blocks of frames, with every check of :func:`facemotion.io.trc.read_trc`.

:func:`open_trc_blocks` reads the header (lines 1-5, the same checks as ``read_trc``);
:meth:`TrcBlocks.blocks` then yields the data lines in blocks of whole lines of about
``block_bytes`` of text, so memory holds one block, never the take. Each block is parsed by
pandas' C parser (quoting off, only an empty field missing); a block that is not plainly regular
(a line with another number of fields, a line of spaces, non-ASCII text, a token the C parser
refuses) is parsed line by line as the exact reader does, which gives its error with the file's
line number. Across blocks the reader carries what the whole-take checks need: the last frame
number (Frame# must increase), the first time and the frame index (the Time column on the
1/DataRate grid, ``t0 + i / rate``, the same floats as the whole-take check), the count of data
lines (NumFrames) and whether the last line has a line end.
"""

from __future__ import annotations

import io
import queue
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.io.base import (
    _Irregular,
    _line_fields,
    _parse_chunk,
    check_readable,
    split_tab_line,
)
from facemotion.io.trc import _trc_header, parse_trc_rows

#: Text per block (about 5,000 frames of 468 markers); the caller's memory bound sets its own.
BLOCK_BYTES = 32 * 2**20
#: Lines wider than this many fields are parsed by numpy's ``loadtxt`` (see _parse_plain).
WIDE_COLUMNS = 3000


@dataclass
class _Carry:
    frames: int = 0            # data lines read so far
    line_no: int = 6           # file line number of the next line
    last_frame: float = np.nan
    last_line: int = 0
    t0: float = np.nan


@dataclass
class TrcBlocks:
    """A TRC file's header, and its data lines in blocks (:meth:`blocks`)."""

    path: Path
    rate: float
    n_frames: int
    labels: list[str]
    scale: float
    units: str
    units_source: str
    offset: int                # byte offset of the first data line

    @property
    def ncol(self) -> int:
        return 2 + 3 * len(self.labels)

    def blocks(self, block_bytes: int = BLOCK_BYTES) -> Iterator[tuple[int, np.ndarray]]:
        """(index of the block's first frame, its points (frames, markers, 3) in mm), in order.

        InputError as :func:`~facemotion.io.trc.read_trc` gives it: a line with too few fields
        or text beyond them, a non-numeric value, Frame# not increasing, a Time off the grid,
        other than NumFrames data lines, a last line without a line end."""
        c = _Carry()
        for values, numbers, _ in _ahead(self._parsed(block_bytes)):
            if not len(values):
                continue
            if c.frames + len(values) > self.n_frames:
                raise InputError(f"{self.path}: TRC header says NumFrames={self.n_frames} but "
                                 f"there are more data lines (line {int(numbers[-1])})")
            self._check_time(numbers, values[:, 0], values[:, 1], c)
            start = c.frames
            c.frames += len(values)
            xyz = values[:, 2:].reshape(len(values), len(self.labels), 3)
            if self.scale != 1.0:
                xyz *= self.scale
            yield start, xyz
        if c.frames != self.n_frames:
            raise InputError(f"{self.path}: TRC header says NumFrames={self.n_frames} but "
                             f"there are {c.frames} data lines")
        if c.frames == 0:
            raise InputError(f"{self.path}: TRC file has no frames")

    def _parsed(self, block_bytes: int) -> Iterator[tuple]:
        """:meth:`_parse` of every chunk of whole lines, in order."""
        line_no = _Carry().line_no
        chunks = _line_chunks(self.path, self.offset, block_bytes)
        while True:
            try:
                chunk = next(chunks)
            except StopIteration:
                return
            except _CutShort:
                raise InputError(f"{self.path}: line {line_no}, the last one, has no line "
                                 "end: the file looks cut short") from None
            parsed = self._parse(chunk, line_no)
            line_no += parsed[2]
            yield parsed

    def _parse(self, chunk: bytes, first_line: int):
        """(values (lines x ncol), their line numbers, lines in the chunk incl. blank)."""
        skipped, pos = 0, 0  # the blank line after the header, in the first block
        while chunk.startswith((b"\n", b"\r\n"), pos):
            pos += 1 if chunk[pos] == 10 else 2
            skipped += 1
        quick = _parse_plain(chunk[pos:] if pos else chunk, self.ncol)
        if quick is not None:
            return quick, first_line + skipped + np.arange(len(quick)), skipped + len(quick)
        try:
            fields, data = _line_fields(chunk, ord("\t"), self.ncol, True)
            vals = (_parse_chunk(chunk, b"\t", int(fields.max()), self.ncol, fields.size)
                    if fields.size else np.empty((0, self.ncol)))
            return vals, first_line + np.flatnonzero(data), data.size
        except _Irregular:
            return self._parse_exact(chunk, first_line)

    def _parse_exact(self, chunk: bytes, first_line: int):
        """The exact reader's rules on one block of lines (errors name the file's line)."""
        try:
            text = chunk.decode("utf-8")
        except UnicodeDecodeError:
            raise InputError(f"{self.path}: cannot read TRC text (UnicodeDecodeError)") from None
        lines = text.splitlines(keepends=True)
        rows, numbers = [], []
        for i, line in enumerate(lines, start=first_line):
            if line.strip(" \r\n"):
                rows.append(split_tab_line(line))
                numbers.append(i)
        if not rows:
            return np.empty((0, self.ncol)), np.zeros(0, dtype=np.int64), len(lines)
        values = parse_trc_rows(self.path, numbers, rows, self.ncol)
        return values, np.asarray(numbers), len(lines)

    def _check_time(self, numbers, frame_numbers, times, c: _Carry) -> None:
        """:func:`~facemotion.io.trc.check_trc_time` across blocks (same grid, same floats)."""
        rate = self.rate
        bad = np.flatnonzero(~np.isfinite(frame_numbers) | ~np.isfinite(times))
        if bad.size:
            raise InputError(f"{self.path}: line {int(numbers[bad[0]])}: Frame# and Time must "
                             "be numbers")
        prev = np.concatenate([[c.last_frame], frame_numbers[:-1]])
        steps = np.flatnonzero(~(frame_numbers > prev) & np.isfinite(prev))
        if steps.size:
            i = int(steps[0])
            before = c.last_frame if i == 0 else frame_numbers[i - 1]
            raise InputError(f"{self.path}: line {int(numbers[i])}: Frame# "
                             f"{frame_numbers[i]:g} does not follow {before:g}")
        if c.frames == 0:
            c.t0 = float(times[0])
        grid = c.t0 + np.arange(c.frames, c.frames + times.size) / rate
        off = np.flatnonzero(np.abs(times - grid) > 0.25 / rate)
        if off.size:
            i = int(off[0])
            raise InputError(f"{self.path}: line {int(numbers[i])}: Time {times[i]:.6g} s is "
                             f"off the 1/DataRate grid (expected {grid[i]:.6g} s at {rate:g} "
                             "Hz): a frame is missing, repeated or out of order, or DataRate "
                             "is wrong")
        c.last_frame = float(frame_numbers[-1])
        c.last_line = int(numbers[-1])


def _parse_plain(chunk: bytes, ncol: int) -> np.ndarray | None:
    """The values of a block whose every line is a data line of exactly ``ncol`` fields, or
    None. Checked without a pass per byte in Python or numpy: no line is blank (one row per
    line end), and no line has another number of fields: pyarrow refuses such a line itself;
    for the other parsers (given ``ncol`` columns, so that a line with more fields stops them)
    the tabs must add up to ``ncol - 1`` per line. Lines of up to ``WIDE_COLUMNS`` fields go
    to pyarrow's C++ reader (one thread), wider ones to numpy's C ``loadtxt``: pandas builds
    one column per field, and its overhead per column makes it slower there
    (docs/performance.md, the streamed parsers' table); both parse numbers to the correctly
    rounded float, as the exact reader does. A block either refuses goes to pandas."""
    if not chunk.isascii() or b"\0" in chunk:
        return None
    lines = chunk.count(b"\n")
    narrow = ncol <= WIDE_COLUMNS
    values = _arrow(chunk, ncol) if narrow else None
    if values is None:
        if chunk.count(b"\t") != lines * (ncol - 1):
            return None
        values = None if narrow else _loadtxt(chunk, ncol)
        if values is None:
            values = _pandas(chunk, ncol)
    return values if values is not None and len(values) == lines else None


def _loadtxt(chunk: bytes, ncol: int) -> np.ndarray | None:
    """numpy's C reader (Python's correctly rounded float parsing, the exact reader's); None
    on anything but numbers (an empty field, a token that is not a number)."""
    try:
        values = np.loadtxt(io.BytesIO(chunk), delimiter="\t", dtype=np.float64, ndmin=2,
                            comments=None, quotechar=None)
    except ValueError:
        return None
    return values if values.shape[1] == ncol else None


def _arrow(chunk: bytes, ncol: int) -> np.ndarray | None:
    """pyarrow's CSV reader on one block, one thread (quoting off, an empty field missing);
    None on anything it refuses (a line with another number of fields, a token that is not a
    number)."""
    import pyarrow as pa
    from pyarrow import csv

    names = [str(i) for i in range(ncol)]
    try:
        table = csv.read_csv(
            pa.py_buffer(chunk),
            csv.ReadOptions(column_names=names, use_threads=False, block_size=len(chunk) + 1),
            csv.ParseOptions(delimiter="\t", quote_char=False, double_quote=False),
            csv.ConvertOptions(column_types=dict.fromkeys(names, pa.float64()),
                               null_values=[""], strings_can_be_null=False,
                               quoted_strings_can_be_null=False))
    except (pa.ArrowInvalid, pa.ArrowTypeError, ValueError):
        return None
    out = np.empty((table.num_rows, ncol))
    for i, column in enumerate(table.columns):
        out[:, i] = column.to_numpy(zero_copy_only=False) if column.num_chunks else np.nan
    return out


def _pandas(chunk: bytes, ncol: int) -> np.ndarray | None:
    """pandas' C parser (quoting off, only an empty field missing)."""
    import csv as _csv

    import pandas as pd

    try:
        df = pd.read_csv(io.BytesIO(chunk), sep="\t", header=None, names=range(ncol),
                         index_col=False, dtype=np.float64, engine="c",
                         keep_default_na=False, na_values=[""], quoting=_csv.QUOTE_NONE,
                         skip_blank_lines=True, low_memory=ncol <= WIDE_COLUMNS)
    except (ValueError, TypeError, pd.errors.ParserError):
        return None
    return df.to_numpy(dtype=np.float64)


def _ahead(items: Iterator, depth: int = 2) -> Iterator:
    """``items``, each made in a thread of its own while the caller works on the one before
    (parsing releases the GIL: reading and parsing the next block overlaps the caller's checks,
    Gram and writing on a second core); at most ``depth`` items made and not yet done with
    (the one the caller holds included). An exception of ``items`` is raised here, after the
    items before it, as it would be without the thread. The thread stops when the caller
    stops asking."""
    done, ready, stop = threading.Semaphore(depth), queue.Queue(), threading.Event()

    def make():
        try:
            while True:
                while not done.acquire(timeout=0.05):
                    if stop.is_set():
                        return
                if stop.is_set():
                    return
                try:
                    ready.put((False, next(items)))
                except StopIteration:
                    ready.put((True, None))
                    return
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            ready.put((True, e))
        finally:
            items.close()

    worker = threading.Thread(target=make, name="trc-blocks", daemon=True)
    worker.start()
    try:
        while True:
            end, item = ready.get()
            if end:
                if item is not None:
                    raise item
                return
            yield item
            done.release()
    finally:
        stop.set()
        worker.join()


class _CutShort(Exception):
    """The file's last line has no line end."""


def _line_chunks(path: Path, offset: int, block_bytes: int) -> Iterator[bytearray]:
    """The file from ``offset`` in chunks of whole lines (each read into a buffer of its own,
    the part line at its end moved to the next: one copy of the text); _CutShort after the
    last whole line when text without a line end follows it (the file was cut short)."""
    carry = b""
    with open(path, "rb", buffering=0) as fh:
        fh.seek(offset)
        while True:
            buf = bytearray(len(carry) + block_bytes)
            buf[:len(carry)] = carry
            got = len(carry)
            while got < len(buf):
                k = fh.readinto(memoryview(buf)[got:])
                if not k:
                    break
                got += k
            if got == len(carry):
                if carry.strip(b" \r\n"):
                    raise _CutShort
                return
            del buf[got:]
            cut = buf.rfind(b"\n") + 1
            carry = bytes(buf[cut:])
            if cut:
                del buf[cut:]
                yield buf


def open_trc_blocks(path, units: str | None = None) -> TrcBlocks:
    """A TRC file's header (checked as :func:`~facemotion.io.trc.read_trc` checks it), ready to
    give its data lines in blocks."""
    p = check_readable(path)
    try:
        with open(p, "rb") as fh:
            head = [fh.readline() for _ in range(5)]
            offset = fh.tell()
        lines = [h.decode("utf-8-sig" if i == 0 else "utf-8") for i, h in enumerate(head)]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{p}: cannot read TRC text ({type(e).__name__})") from None
    lines = [x for x in lines if x]
    rate, n_frames, labels, scale, used, source = _trc_header(p, lines, units)
    return TrcBlocks(p, rate, n_frames, labels, scale, used, source, offset)
