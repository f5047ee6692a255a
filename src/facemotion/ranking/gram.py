"""The Gram matrix G = A^T A in one pass over blocks of rows, at the machine's GEMM rate.

Pivoted QR of A makes its choices from inner products of A's columns only, so one pass

    G = sum_b A_b^T A_b          (A_b: consecutive blocks of rows of A)

is all the ranking reads of A (see :mod:`facemotion.ranking.routes`, route "gram"). Each block's
product is one level-3 BLAS call (a symmetric rank-k update, ``syrk``: rows x n x (n + 1)
flops, half a general matrix product's), on a block small enough to stay in cache and to bound
memory. Two ways to use several cores:

``"rows"`` (few columns)
    each thread takes a contiguous share of the rows and sums its own G with single-threaded
    BLAS (numpy's ``b.T @ b``, which calls syrk and lets other threads run); the partial sums
    are added at the end. BLAS's own threads would split the small n x n output, which leaves
    them waiting on each other. Memory: two n x n arrays per thread.
``"blas"`` (many columns)
    one G updated in place by scipy's ``dsyrk`` (beta = 1) per block, with BLAS using the
    threads. The output is large enough to share out, and only one n x n array is held.

The cut between them is ``ROWS_MAX_N`` columns (measured: benchmarks/bench_qr.py reports the
rate of both routes against the GEMM peak of the same run).
"""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np

#: Up to this many columns the threads split the rows (route "rows"); above, BLAS threads.
ROWS_MAX_N = 256
#: Bytes of A per block in the in-memory case (whole frames; fits the last-level cache).
CACHE_BLOCK_BYTES = 2 * 2**20
ROUTES = ("auto", "rows", "blas")


def blas_threads() -> int:
    """Threads the caller allows BLAS: OPENBLAS_NUM_THREADS / OMP_NUM_THREADS (Snakemake sets
    them to the rule's ``threads``), else the CPUs this process may run on."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        v = os.environ.get(var, "").strip()
        if v.isdigit() and int(v) > 0:
            return int(v)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


@functools.cache
def _blas_controller(scipy_loaded: bool):
    """threadpoolctl's view of the loaded BLAS libraries, found once per state: looking them
    up costs a few milliseconds, a tenth of a Gram pass at 10x the paper's frames. numpy's and
    scipy's wheels each bring their own OpenBLAS, so the view is taken again once scipy.linalg
    has been imported (and loaded its library)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def blas_limit(threads: int):
    """Context manager: numpy's and scipy's BLAS limited to ``threads`` threads inside it."""
    return _blas_controller("scipy.linalg" in sys.modules).limit(limits=int(threads),
                                                                 user_api="blas")


def _blocks_rows(n: int, block_bytes: int) -> int:
    rows = max(3, block_bytes // (8 * max(n, 1)))
    return rows - rows % 3


def _parts(source, k: int) -> list:
    """k contiguous shares of the rows of ``source`` (an array or a RowBlocks)."""
    rows = source.shape[0]
    cuts = [3 * ((rows // 3) * i // k) for i in range(k + 1)]
    if isinstance(source, np.ndarray):
        return [source[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]
    from facemotion.ingest.displacement_file import RowBlocks

    parts = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        ranges, r = [], 0
        for lo, hi in source.ranges:  # map [a, b) of the concatenated rows onto file ranges
            s, e = max(lo, lo + a - r), min(hi, lo + b - r)
            if e > s:
                ranges.append((s, e))
            r += hi - lo
        if ranges:
            parts.append(RowBlocks(source.source, ranges))
    return parts


def _iter_blocks(source, block_rows: int) -> Iterator[np.ndarray]:
    if isinstance(source, np.ndarray):
        for a in range(0, source.shape[0], block_rows):
            yield source[a:a + block_rows]
    else:
        yield from source.blocks(block_rows)


def _gram_rows(source, block_rows: int) -> np.ndarray:
    """sum of b^T b over the blocks of source, single-threaded BLAS (numpy calls syrk)."""
    n = source.shape[1]
    G = np.zeros((n, n))
    tmp = np.empty((n, n))
    for b in _iter_blocks(source, block_rows):
        if not b.flags.c_contiguous:
            b = np.ascontiguousarray(b)
        np.matmul(b.T, b, out=tmp)  # numpy recognises b^T b and calls syrk
        G += tmp
    return G


def _gram_blas(source, block_rows: int) -> np.ndarray:
    """One upper-triangular G updated in place by dsyrk (BLAS threads inside each call)."""
    from scipy.linalg.blas import dsyrk

    n = source.shape[1]
    G = np.zeros((n, n), order="F")
    for b in _iter_blocks(source, block_rows):
        if not b.flags.c_contiguous:
            b = np.ascontiguousarray(b)
        # b is C-ordered (m x n), so b.T is Fortran-ordered (n x m): G += b.T (b.T)^T = b^T b
        G = dsyrk(1.0, b.T, beta=1.0, c=G, trans=0, lower=0, overwrite_c=1)
    iu = np.triu_indices(n, 1)
    G[(iu[1], iu[0])] = G[iu]  # mirror the upper triangle
    return np.ascontiguousarray(G)


def gram(source, *, threads: int | None = None, route: str = "auto",
         block_rows: int | None = None) -> np.ndarray:
    """G = A^T A (n x n) in one pass over blocks of rows of ``source``.

    source: an array A (rows x n) or a :class:`~facemotion.ingest.displacement_file.RowBlocks` (A on
    disk, read block by block). threads: how many cores to use (default :func:`blas_threads`).
    route: "rows", "blas" or "auto" (rows up to ``ROWS_MAX_N`` columns). block_rows: rows per
    block (default: ~2 MiB of A in memory, the RowBlocks default on disk).
    """
    if route not in ROUTES:
        raise ValueError(f"route must be one of {ROUTES}, got {route!r}")
    rows, n = source.shape
    threads = blas_threads() if threads is None else max(1, int(threads))
    if route == "auto":
        route = "rows" if n <= ROWS_MAX_N else "blas"
    if block_rows is None and isinstance(source, np.ndarray):
        block_rows = _blocks_rows(n, CACHE_BLOCK_BYTES)
    if route == "blas":
        with blas_limit(threads):
            return _gram_blas(source, block_rows)
    parts = _parts(source, threads) if rows >= 3 * threads else [source]
    with blas_limit(1):
        if len(parts) == 1:
            return _gram_rows(parts[0], block_rows)
        with ThreadPoolExecutor(len(parts)) as ex:
            partial = list(ex.map(lambda p: _gram_rows(p, block_rows), parts))
    G = partial[0]
    for P in partial[1:]:
        G += P
    return G


def gemm_rate(threads: int, size: int = 2000, repeats: int = 3) -> float:
    """This machine's double-precision GEMM rate (GFLOP/s, best of ``repeats``) with
    ``threads`` BLAS threads: the peak the Gram pass is compared with."""
    import time

    from threadpoolctl import threadpool_limits

    rng = np.random.default_rng(0)
    X, Y = rng.standard_normal((size, size)), rng.standard_normal((size, size))
    out = np.empty((size, size))
    best = np.inf
    with threadpool_limits(threads, user_api="blas"):
        np.matmul(X, Y, out=out)  # warm up
        for _ in range(repeats):
            t0 = time.perf_counter()
            np.matmul(X, Y, out=out)
            best = min(best, time.perf_counter() - t0)
    return 2.0 * size**3 / best / 1e9


def gram_flops(rows: int, n: int) -> float:
    """Flops of A^T A by syrk (the upper triangle): rows x n x (n + 1)."""
    return float(rows) * n * (n + 1)
