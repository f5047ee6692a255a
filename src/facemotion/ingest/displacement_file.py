"""The displacements file: an uncompressed npz whose matrix A is read in blocks of rows.

Layout: a zip archive of ``.npy`` entries, all STORED (no compression), with fixed entry dates
so a rerun writes the same bytes; ``np.load`` reads it like any npz. ``A.npy`` is the first
entry and C-ordered, so its values are one contiguous run of bytes at a known offset: a reader
takes any range of rows with one positioned read, and a consumer that streams A (the Gram
matrix, TSQR, the error curves) holds one block at a time, however long the recording.

Why not compressed: deflate saved 5 % on displacement data at 27 MB/s, i.e. the
writer and every reader spent seconds to save almost nothing, and a deflated entry cannot be
read from the middle. Why not zarr: one more dependency, a directory of chunk files instead of
one file (awkward for Snakemake outputs and checksummed provenance), and nothing to gain here
since the data do not compress. Why not a memory map: pages of a mapped file that were read stay
in the process's resident set until the kernel needs them back, so a pass over a 4 GB A through
``np.memmap`` shows as 4 GB of RSS; positioned reads into one reused buffer do not.

Files written by older versions (deflated entries) are still read, whole, through ``np.load``.
"""

from __future__ import annotations

import os
import struct
import tempfile
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from facemotion.errors import InputError, MissingFileError
from facemotion.ingest.displacements import Displacements, check_sentence_indices
from facemotion.io.atomic import current_umask

if TYPE_CHECKING:
    pass


#: Default bound on the bytes of A one block holds (the ``block_mb`` setting of consumers).
BLOCK_BYTES = 64 * 2**20


_ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed entry date: byte-identical files on rerun


_ZIP64_LIMIT = (1 << 31) - 1


NEED = ("A", "labels", "sentences", "row_sentence", "row_frame", "rate", "fill_mask",
        "head_residual", "neutral")


def block_rows_for(n_columns: int, block_bytes: int = BLOCK_BYTES) -> int:
    """Rows per block (a multiple of 3: whole frames) so that one block holds <= block_bytes."""
    rows = max(3, int(block_bytes) // (8 * max(int(n_columns), 1)))
    return rows - rows % 3


def _npy_header(shape: tuple[int, ...], dtype) -> bytes:
    """The .npy header (format 1.0 or 2.0) of a C-ordered array of this shape and dtype."""
    import io

    d = {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)), "fortran_order": False,
         "shape": tuple(int(s) for s in shape)}
    buf = io.BytesIO()
    try:
        np.lib.format.write_array_header_1_0(buf, d)
    except ValueError:  # header too long for 1.0
        buf = io.BytesIO()
        np.lib.format.write_array_header_2_0(buf, d)
    return buf.getvalue()


def _entry(zf: zipfile.ZipFile, name: str, nbytes: int):
    info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_STORED
    info.external_attr = 0o644 << 16
    info.file_size = nbytes
    return zf.open(info, "w", force_zip64=nbytes > _ZIP64_LIMIT)


def _write_array(zf: zipfile.ZipFile, name: str, a: np.ndarray) -> None:
    a = np.ascontiguousarray(a)
    if a.dtype.kind in "UO":
        a = np.asarray(a, dtype=str)
    head = _npy_header(a.shape, a.dtype)
    with _entry(zf, name, len(head) + a.nbytes) as fh:
        fh.write(head)
        if a.size:
            fh.write(a.reshape(-1).view(np.uint8))


class DisplacementsWriter:
    """Write a displacements file with A streamed in blocks of rows (atomic: temp + rename).

    ``rows`` (3 x frames) and the labels are fixed up front; :meth:`write_rows` appends rows of
    A in order; :meth:`close` takes the other arrays (see :class:`Displacements`) and renames the
    file into place. On an exception nothing is left behind.
    """

    def __init__(self, path, labels: Sequence[str], rows: int):
        self.path = Path(path)
        self.labels = [str(x) for x in labels]
        self.rows = int(rows)
        self.n = len(self.labels)
        self.written = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp",
                                         dir=self.path.parent)
        self._fh = os.fdopen(fd, "wb")
        try:
            self._zf = zipfile.ZipFile(self._fh, "w", allowZip64=True)
            head = _npy_header((self.rows, self.n), np.float64)
            self._a = _entry(self._zf, "A", len(head) + 8 * self.rows * self.n)
            self._a.write(head)
        except BaseException:
            self.abort()
            raise

    def write_rows(self, block: np.ndarray) -> None:
        block = np.ascontiguousarray(block, dtype=np.float64)
        if block.ndim != 2 or block.shape[1] != self.n:
            self.abort()
            raise InputError(f"{self.path}: a block of A has shape {block.shape}, expected "
                             f"(rows, {self.n})")
        if self.written + block.shape[0] > self.rows:
            self.abort()
            raise InputError(f"{self.path}: more than the {self.rows} rows declared for A")
        try:
            if block.size:
                self._a.write(block.reshape(-1).view(np.uint8))
        except OSError as e:
            self.abort()
            raise OSError(e.errno, e.strerror, str(self.path)) from None
        self.written += block.shape[0]

    def close(self, **arrays) -> None:
        """Finish A and write the other arrays (sentences, row_sentence, row_frame, rate,
        fill_mask, head_residual, neutral, optional sentence_neutral)."""
        try:
            if self.written != self.rows:
                raise InputError(f"{self.path}: {self.written} rows of A written, "
                                 f"{self.rows} declared")
            self._a.close()
            _write_array(self._zf, "labels", np.array(self.labels, dtype=str))
            for name, a in arrays.items():
                if a is not None:
                    _write_array(self._zf, name, np.asarray(a))
            self._zf.close()
            self._fh.close()
            os.chmod(self._tmp, 0o666 & ~current_umask())  # mkstemp made it 0600
            os.replace(self._tmp, self.path)
        except OSError as e:  # disk full, file-size limit: name the output, not the temp file
            self.abort()
            raise OSError(e.errno, e.strerror, str(self.path)) from None
        except BaseException:
            self.abort()
            raise

    def abort(self) -> None:
        for closer in (getattr(self, "_a", None), getattr(self, "_zf", None), self._fh):
            try:
                if closer is not None:
                    closer.close()
            except Exception:  # noqa: BLE001 - best effort while failing
                pass
        if os.path.exists(self._tmp):
            os.unlink(self._tmp)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self.abort()


def write_displacements(path, d, block_rows: int | None = None) -> None:
    """Write a :class:`~facemotion.ingest.displacements.Displacements` (A streamed in blocks)."""
    rows, n = d.A.shape
    w = DisplacementsWriter(path, d.labels, rows)
    step = block_rows or block_rows_for(n)
    for a in range(0, rows, step):
        w.write_rows(d.A[a:a + step])
    w.close(sentences=np.array(d.sentences, dtype=str),
            row_sentence=d.row_sentence.astype(np.int64),
            row_frame=d.row_frame.astype(np.int64), rate=np.array(d.rate),
            fill_mask=d.fill_mask.astype(bool), head_residual=d.head_residual,
            neutral=d.neutral, sentence_neutral=d.sentence_neutral)


@dataclass(frozen=True)
class _Npy:
    offset: int          # byte offset of the array's data in the file
    shape: tuple[int, ...]
    dtype: np.dtype


def _stored_entries(path: Path) -> dict[str, _Npy] | None:
    """Offsets of the STORED .npy entries, or None if any entry is compressed."""
    out = {}
    with open(path, "rb") as fh, zipfile.ZipFile(fh) as zf:
        for info in zf.infolist():
            if info.compress_type != zipfile.ZIP_STORED:
                return None
            fh.seek(info.header_offset)
            local = fh.read(30)
            if local[:4] != b"PK\x03\x04":
                raise InputError(f"{path}: damaged zip entry {info.filename!r}")
            name_len, extra_len = struct.unpack("<HH", local[26:30])
            fh.seek(info.header_offset + 30 + name_len + extra_len)
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            if fortran and len(shape) > 1:
                raise InputError(f"{path}: entry {info.filename!r} is Fortran-ordered")
            out[info.filename.removesuffix(".npy")] = _Npy(fh.tell(), tuple(shape), dtype)
    return out


def _read_npy(path: Path, e: _Npy, mmap: bool = False) -> np.ndarray:
    if e.dtype.hasobject:
        raise InputError(f"{path}: object arrays are not allowed in a displacements file")
    count = int(np.prod(e.shape, dtype=np.int64))
    if mmap and count:
        return np.memmap(path, dtype=e.dtype, mode="r", offset=e.offset, shape=e.shape)
    with open(path, "rb") as fh:
        fh.seek(e.offset)
        a = np.fromfile(fh, dtype=e.dtype, count=count)
    if a.size != count:
        raise InputError(f"{path}: truncated displacements file")
    return a.reshape(e.shape)


class DisplacementsFile:
    """A displacements file opened for block reading: the small arrays in memory, A on disk.

    Attributes mirror :class:`~facemotion.ingest.displacements.Displacements` (labels, sentences,
    row_sentence, row_frame, rate, fill_mask (memory-mapped), head_residual, neutral,
    sentence_neutral); ``shape`` is A's shape. :meth:`rows` gives a :class:`RowBlocks` view
    of some sentences; :meth:`load` reads everything into a Displacements.
    """

    def __init__(self, path):
        p = Path(path)
        if not p.is_file():
            raise MissingFileError(f"{p}: displacements file not found")
        self.path = p
        try:
            entries = _stored_entries(p)
        except (OSError, ValueError, zipfile.BadZipFile, struct.error) as e:
            raise InputError(f"{p}: cannot read displacements npz ({e})") from None
        self._legacy = None
        if entries is None:  # compressed (older file): read it whole
            try:
                with np.load(p, allow_pickle=False) as z:
                    self._legacy = {k: z[k] for k in z.files}
            except (OSError, ValueError, zipfile.BadZipFile) as e:
                raise InputError(f"{p}: cannot read displacements npz ({e})") from None
            names = set(self._legacy)
        else:
            names = set(entries)
        lacking = [k for k in NEED if k not in names]
        if lacking:
            raise InputError(f"{p}: displacements file lacks array(s) {', '.join(lacking)}")
        self._entries = entries

        def get(name, mmap=False):
            if self._legacy is not None:
                return self._legacy.get(name)
            return _read_npy(p, entries[name], mmap) if name in entries else None

        rate = get("rate")
        if np.size(rate) != 1:
            raise InputError(f"{p}: 'rate' must be a single number, got shape {rate.shape}")
        self.rate = float(np.ravel(rate)[0])
        self.labels = [str(x) for x in get("labels")]
        self.sentences = [str(x) for x in get("sentences")]
        self.row_sentence = np.asarray(get("row_sentence"), dtype=np.int64)
        self.row_frame = np.asarray(get("row_frame"), dtype=np.int64)
        self.fill_mask = get("fill_mask", mmap=True)
        self.head_residual = np.asarray(get("head_residual"), dtype=float)
        self.neutral = np.asarray(get("neutral"), dtype=float)
        sn = get("sentence_neutral")
        self.sentence_neutral = None if sn is None else np.asarray(sn, dtype=float)
        shape = self._legacy["A"].shape if self._legacy is not None else entries["A"].shape
        if len(shape) != 2 or shape[1] != len(self.labels) or shape[0] % 3 \
                or self.row_sentence.shape != (shape[0],) or self.row_frame.shape != (shape[0],):
            raise InputError(f"{p}: inconsistent shapes: A {shape}, {len(self.labels)} labels, "
                             f"row_sentence {self.row_sentence.shape}, row_frame "
                             f"{self.row_frame.shape}")
        if self._legacy is None and entries["A"].dtype != np.float64:
            raise InputError(f"{p}: A must be float64, got {entries['A'].dtype}")
        self.shape = (int(shape[0]), int(shape[1]))

    # -- rows of A ----------------------------------------------------------------------------
    def read_rows(self, start: int, stop: int, out: np.ndarray | None = None) -> np.ndarray:
        """Rows [start, stop) of A, in ``out`` if given (a C-contiguous float64 buffer)."""
        n = self.shape[1]
        m = stop - start
        if out is None:
            out = np.empty((m, n))
        else:
            out = out[:m]
        if self._legacy is not None:
            out[...] = self._legacy["A"][start:stop]
            return out
        mv = memoryview(out).cast("B")
        want = mv.nbytes
        with open(self.path, "rb", buffering=0) as fh:
            fh.seek(self._entries["A"].offset + 8 * n * start)
            got = 0
            while got < want:
                k = fh.readinto(mv[got:])
                if not k:
                    raise InputError(f"{self.path}: truncated displacements file")
                got += k
        return out

    def rows(self, sentence_indices=None) -> RowBlocks:
        """The rows of these sentences (indices into ``sentences``; default all), in order."""
        if sentence_indices is None:
            return RowBlocks(self, [(0, self.shape[0])])
        ranges = []
        for s in check_sentence_indices(sentence_indices, len(self.sentences)):
            idx = np.flatnonzero(self.row_sentence == s)
            if idx.size:
                # a sentence's rows are contiguous in A (sentences are stacked)
                ranges.append((int(idx[0]), int(idx[-1]) + 1))
        return RowBlocks(self, ranges)

    def load(self):
        """Everything in memory, as a :class:`~facemotion.ingest.displacements.Displacements`."""
        from facemotion.ingest.displacements import Displacements

        A = self._legacy["A"] if self._legacy is not None else self.read_rows(0, self.shape[0])
        return Displacements(
            A=A, labels=self.labels, sentences=self.sentences, row_sentence=self.row_sentence,
            row_frame=self.row_frame, rate=self.rate, fill_mask=np.asarray(self.fill_mask),
            head_residual=self.head_residual, neutral=self.neutral,
            sentence_neutral=self.sentence_neutral)


class RowBlocks:
    """Some rows of an on-disk A (ranges of rows, in order), read in blocks.

    ``shape``, ``labels``; :meth:`blocks` yields C-contiguous float64 blocks of at most
    ``block_rows`` rows (a multiple of 3) that share one buffer: use each before the next.
    """

    def __init__(self, source: DisplacementsFile, ranges: list[tuple[int, int]]):
        self.source = source
        self.ranges = [(int(a), int(b)) for a, b in ranges if b > a]
        self.labels = list(source.labels)
        self.shape = (sum(b - a for a, b in self.ranges), source.shape[1])

    def blocks(self, block_rows: int | None = None) -> Iterator[np.ndarray]:
        step = block_rows or block_rows_for(self.shape[1])
        buf = np.empty((min(step, max(self.shape[0], 1)), self.shape[1]))
        for a, b in self.ranges:
            for s in range(a, b, step):
                yield self.source.read_rows(s, min(b, s + step), out=buf)

    def read(self) -> np.ndarray:
        """All these rows in memory (3F x n)."""
        out = np.empty(self.shape)
        r = 0
        for a, b in self.ranges:
            self.source.read_rows(a, b, out=out[r:r + b - a])
            r += b - a
        return out

    def columns(self, cols, block_rows: int | None = None) -> np.ndarray:
        """A[:, cols] for these rows, gathered block by block."""
        cols = np.asarray(cols, dtype=np.intp)
        out = np.empty((self.shape[0], cols.size))
        r = 0
        for blk in self.blocks(block_rows):
            out[r:r + blk.shape[0]] = blk[:, cols]
            r += blk.shape[0]
        return out


def open_displacements(path) -> DisplacementsFile:
    """Open a displacements file for block reading (A stays on disk)."""
    return DisplacementsFile(path)


def save_displacements(path, d: Displacements) -> None:
    """Write ``d`` as an uncompressed npz whose A can be read in blocks of rows (see
    :mod:`facemotion.ingest.displacement_file`); fixed entry dates: reruns are byte-identical."""
    from facemotion.ingest.displacement_file import write_displacements

    write_displacements(path, d)


def load_displacements(path) -> Displacements:
    """Read a file written by :func:`save_displacements` (or an older deflated npz) whole.

    For A larger than memory use :func:`facemotion.ingest.displacement_file.open_displacements`."""
    from facemotion.ingest.displacement_file import open_displacements

    return open_displacements(path).load()
