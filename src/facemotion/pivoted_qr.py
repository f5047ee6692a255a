"""Marker ranking by QR with column pivoting (Lucero & Munhall 2008, Sec. III).

The displacement matrix A (3F x n, frame-major rows, one column per marker, mm) is factored as

    A P = Q R                                     (QR with column pivoting, Golub & Van Loan 5.4)

The first pivot is the marker with the largest motion; each later pivot is the marker whose
motion is least explained by the markers already chosen: |r_kk| is the norm of its component
orthogonal to the span of the previous pivots (a 2-norm of mm values, so in mm).

Normalisation of R ("R values normalized to the size of R", Fig. 2).  ``R_NORMALISATIONS``:

``"none"`` (default)
    |r_kk| itself, the 2-norm (mm) of the pivot's orthogonal component, and ||R22||_2 compared
    with epsilon as printed in Sec. III.  This is the only reading under which the paper's
    r56 = 22.70 mm is a possible size for the 56th pivot (see the README's arithmetic).
``"per_coordinate"``
    |r_kk| / sqrt(3M): the RMS of that component per coordinate sample (``r_rms``).
``"per_frame"``
    |r_kk| / sqrt(M): its RMS 3-D size per frame.

Epsilon-rank (Sec. III, eq. 1): partition R after k pivots, R22 = R[k:, k:]; the paper's
epsilon-rank is the smallest k with ||R22||_2 <= epsilon (``epsilon_rank``), which bounds the
singular values sigma_{k+1}(A) <= ||R22||_2 (Chan 1987).  Since R[k+1:, k+1:] is a submatrix of
R[k:, k:], ||R22||_2 is non-increasing in k and a bisection needs only O(log n) 2-norms.  The
older count of diagonal entries above epsilon is kept beside it (``diagonal_count``); it is never
larger than the epsilon-rank, because |r_jj| <= ||R[k:, k:]||_2 for every k <= j.

Three routes give the same pivots and the same |R| (up to the sign of each row of R, which we fix
so that diag(R) >= 0):

``"scipy"``
    ``scipy.linalg.qr(A, pivoting=True)`` on the full matrix (LAPACK dgeqp3).  The reference.
``"tsqr"``
    One streaming pass of unpivoted QR over row blocks, ``R0 = qr([R0; A_block])`` (TSQR), giving
    an n x n R0 with A = Q0 R0.  Column norms and all inner products of A are those of R0
    (A^T A = R0^T R0), so pivoted QR of R0 makes exactly the choices pivoted QR of A would make.
``"gram"``
    One pass G = A^T A (BLAS syrk), then diagonal-pivoting Cholesky of G: at step k the Schur
    complement diagonal is the squared norm of each column's residual orthogonal to the pivots
    so far, so choosing its largest entry is the QR pivot rule, and the Cholesky factor is R.
    Accuracy: forming G squares the condition number.  The Schur complement diagonal r_kk^2 is
    computed with an absolute error of about eps * r_11^2, so the relative error of r_kk is about
    eps * (r_11 / r_kk)^2 / 2.  Once r_kk / r_11 approaches sqrt(eps) ~ 1e-8 the Gram route
    returns noise (and may pick different pivots among the near-dependent columns).
``"auto"``
    The Gram route, falling back to TSQR when some r_kk / r_11 < ``GRAM_RATIO_LIMIT`` (1e-4,
    i.e. a relative error in r_kk above ~1e-8), e.g. when a marker is a copy of another; with
    ``k_max`` set and at least ``RANDOMIZED_MIN_N`` markers, the randomized route.
``"randomized"``
    The first ``k_max`` pivots from a Gaussian sketch of A, refined on A itself (see
    :mod:`facemotion.randomized_selection`); two passes over A of O(rows n k_max) flops
    instead of the Gram's O(rows n^2).

A may be an array or a :class:`facemotion.displacement_file.RowBlocks` (A on disk): the
"gram", "tsqr" and "randomized" routes read it in blocks of rows, holding one block at a time;
"scipy" reads it whole. The Gram pass runs on ``threads`` cores (:mod:`facemotion.gram`).

Fewer rows than markers (e.g. 150 frames of 457 landmarks): A has rank at most rows, so only
the first ``rows`` pivots are chosen by the QR rule; the others are exact combinations of them
and follow in their original order with r = 0. ``MarkerRanking.n_ranked`` says how many pivots
were ranked (also fewer when ``k_max`` limits the ranking), and a warning is logged.

Bad input raises :class:`facemotion.errors.InputError`: NaN or inf in A, and a static marker (a
column whose largest absolute value is below 1e-12 mm: it has no motion to rank, and its r_kk
would be exactly zero).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.linalg.lapack

from facemotion.errors import InputError

#: Auto route: use the Gram matrix only while every r_kk / r_11 is above this ratio.
GRAM_RATIO_LIMIT = 1e-4
#: A marker whose largest absolute displacement is below this (mm) is static.
STATIC_MM = 1e-12
#: Rows per block of the streaming TSQR pass (a multiple of 3: whole frames).
CHUNK_ROWS = 3 * 4096
#: Auto route: the randomized selection from this many markers on (when k_max is set).
RANDOMIZED_MIN_N = 2000
_EPS = np.finfo(float).eps
METHODS = ("auto", "gram", "tsqr", "scipy", "randomized")
log = logging.getLogger("facemotion")
#: Readings of "R values normalized to the size of R" (Fig. 2); see the module notes.
R_NORMALISATIONS = ("none", "per_coordinate", "per_frame")
DEFAULT_R_NORMALISATION = "none"


def r_scale(rows: int, normalisation: str = DEFAULT_R_NORMALISATION) -> float:
    """The divisor applied to R (and R22) under a normalisation, for A with ``rows`` = 3M."""
    if normalisation == "none":
        return 1.0
    if normalisation == "per_coordinate":
        return float(np.sqrt(rows))             # RMS per coordinate sample
    if normalisation == "per_frame":
        return float(np.sqrt(rows / 3.0))       # RMS 3-D size per frame
    raise InputError(f"r_normalisation: unknown normalisation {normalisation!r}; use one of "
                     f"{', '.join(R_NORMALISATIONS)}")


def implied_rms_per_coordinate(r_value: float, rows: int,
                               normalisation: str = DEFAULT_R_NORMALISATION) -> float:
    """The RMS per coordinate sample (mm) of a pivot's orthogonal component that an R value
    quoted under ``normalisation`` implies for A with ``rows`` = 3M rows: r * scale / sqrt(3M).

    E.g. the paper's r56 = 22.70 mm with 3M = 27,000: 0.14 mm under "none", 22.70 mm under
    "per_coordinate", 13.1 mm under "per_frame" (README, "Normalisation of R").
    """
    return float(r_value) * r_scale(rows, normalisation) / float(np.sqrt(rows))


@dataclass(frozen=True)
class MarkerRanking:
    """Result of QR with column pivoting of A (A P = Q R).

    order: pivot indices into the original columns (``order[0]`` is the first pivot).
    labels_in_order: marker labels in pivot order.
    R: n x n upper triangular factor, columns in pivot order, diag(R) >= 0.
    r: |diag R| (mm * sqrt(rows)).
    r_rms: r / sqrt(rows): RMS size (mm) of each marker's motion orthogonal to the markers
        ranked before it.
    rows: number of rows of A (3 x frames).
    labels: marker labels in the original column order.
    method: the route actually used ("gram", "tsqr", "scipy" or "randomized").
    rtol: relative tolerance on r_kk / r_11 below which a pivot counts as numerically zero.
    n_ranked: pivots chosen by the QR rule: min(rows, n, k_max). Later ones follow in their
        original order (fewer rows than markers: r = 0, exact combinations of the ranked) or,
        beyond k_max, by decreasing residual (r = NaN, rows of R not computed).
    """

    order: np.ndarray
    labels_in_order: list[str]
    R: np.ndarray
    r: np.ndarray
    r_rms: np.ndarray
    rows: int
    labels: list[str]
    method: str
    rtol: float
    n_ranked: int | None = None

    def __post_init__(self):
        if self.n_ranked is None:
            object.__setattr__(self, "n_ranked", len(self.labels))

    @property
    def n(self) -> int:
        return len(self.labels)

    def normalised_r(self, normalisation: str = DEFAULT_R_NORMALISATION) -> np.ndarray:
        """|r_kk| under a normalisation of R (``R_NORMALISATIONS``), mm."""
        return self.r / r_scale(self.rows, normalisation)

    def to_frame(self, normalisation: str = DEFAULT_R_NORMALISATION) -> pd.DataFrame:
        """The ranking as a table, in pivot order: ``order`` (1-based), ``marker``, ``r`` =
        |r_kk| (mm), ``r_rms`` and ``r_rms_frame`` (|r_kk| per coordinate sample and per frame,
        mm), ``r_normalised`` under ``normalisation`` (named in ``r_normalisation``), and
        ``ranked`` (False past the pivots the QR rule chose)."""
        return pd.DataFrame({
            "order": range(1, len(self.r) + 1),
            "marker": self.labels_in_order,
            "r": self.r,
            "r_rms": self.normalised_r("per_coordinate"),
            "r_rms_frame": self.normalised_r("per_frame"),
            "r_normalised": self.normalised_r(normalisation),
            "r_normalisation": normalisation,
            # False past the pivots the QR rule chose (fewer rows than markers, or k_max)
            "ranked": [i < self.n_ranked for i in range(len(self.r))],
        })

    def numerical_rank(self) -> int:
        """Number of pivots with r_kk > rtol * r_11 (R11 of that size is safely invertible)."""
        if self.r.size == 0 or self.r[0] == 0:
            return 0
        return int(np.count_nonzero(self.r[: self.n_ranked] > self.rtol * self.r[0]))


def _is_blocks(A) -> bool:
    """A on disk, read in blocks (:class:`facemotion.displacement_file.RowBlocks`)."""
    return hasattr(A, "blocks") and hasattr(A, "shape") and not isinstance(A, np.ndarray)


def _unpack(A, labels):
    """Accept a plain array + labels, or a Displacements-like object with .A and .labels,
    or a RowBlocks (kept on disk)."""
    if _is_blocks(A):
        return A, [str(x) for x in (A.labels if labels is None else labels)]
    if labels is None and hasattr(A, "A") and hasattr(A, "labels"):
        return np.asarray(A.A, dtype=float), [str(x) for x in A.labels]
    if labels is None:
        raise InputError("labels: marker labels are required with a plain displacement matrix")
    return np.asarray(A, dtype=float), [str(x) for x in labels]


def check_displacements(A: np.ndarray, labels: Sequence[str], *, name: str = "A") -> None:
    """Shape checks shared by every route: 2-D, one label per column, whole frames.

    Fewer rows than markers is allowed: the ranking stops at the row count (module docstring).
    """
    if len(A.shape) != 2:
        raise InputError(f"{name}: displacement matrix must be 2-D (3F x n), got shape {A.shape}")
    rows, n = A.shape
    if len(labels) != n:
        raise InputError(f"labels: {len(labels)} labels for {n} marker columns of {name}")
    if len(set(labels)) != n:
        dup = sorted({x for x in labels if list(labels).count(x) > 1})
        raise InputError(f"labels: duplicate marker labels {', '.join(dup)}")
    if n == 0:
        raise InputError(f"{name}: no marker columns")
    if rows % 3:
        raise InputError(f"{name}: {rows} rows is not a multiple of 3 (x, y, z per frame)")
    if rows == 0:
        raise InputError(f"{name}: no frames")


def nonfinite_markers(A: np.ndarray, labels: Sequence[str]) -> list[str]:
    if _is_blocks(A):
        bad = np.zeros(A.shape[1], dtype=bool)
        for blk in A.blocks():
            bad |= ~np.isfinite(blk).all(axis=0)
    else:
        bad = ~np.isfinite(A).all(axis=0)
    return [labels[j] for j in np.flatnonzero(bad)]


def _raise_nonfinite(A, labels, name="A"):
    bad = nonfinite_markers(A, labels)
    raise InputError(f"{name}: NaN or inf displacements in marker(s) {', '.join(bad)}")


def _check_column_norms(A, labels, sq_norms, name="A"):
    """NaN/inf and static markers, from the squared column norms of a pass already made.

    max|a_j| <= ||a_j|| <= sqrt(rows) max|a_j|, so a column is certainly moving when
    ||a_j|| >= sqrt(rows) * STATIC_MM; only the few below are looked at directly.
    """
    if not np.all(np.isfinite(sq_norms)):
        _raise_nonfinite(A, labels, name)
    suspects = np.flatnonzero(np.sqrt(sq_norms) < np.sqrt(A.shape[0]) * STATIC_MM)
    if suspects.size:
        cols = A.columns(suspects) if _is_blocks(A) else A[:, suspects]
        peak = np.max(np.abs(cols), axis=0)
    static = [labels[j] for j, p in zip(suspects, peak if suspects.size else [], strict=True)
              if p < STATIC_MM]
    if static:
        raise InputError(
            f"{name}: marker(s) {', '.join(static)} never move (max |displacement| < "
            f"{STATIC_MM:g} mm): a static marker has no motion to rank; drop it"
        )


# --------------------------------------------------------------------------------------------
# building blocks: TSQR update, Gram matrix, pivoted Cholesky
# --------------------------------------------------------------------------------------------


def update_r(R0: np.ndarray | None, A_block: np.ndarray) -> np.ndarray:
    """TSQR update: the R factor of [R0; A_block] (mode 'r'), so that R^T R = R0^T R0 + B^T B.

    Feeding row blocks one at a time gives the R of the whole stacked matrix in one pass.
    Returns a (min(rows so far, n) x n) upper-trapezoidal array.
    """
    A_block = np.asarray(A_block, dtype=float)
    stacked = A_block if R0 is None else np.vstack([R0, A_block])
    R = scipy.linalg.qr(stacked, mode="r", check_finite=False)[0]
    return R[: min(stacked.shape)]


def tsqr_r(A: np.ndarray, chunk_rows: int = CHUNK_ROWS) -> np.ndarray:
    """n x n R0 with A = Q0 R0 by streaming TSQR over row blocks (one pass over A; A may be
    a RowBlocks on disk)."""
    R0 = None
    if _is_blocks(A):
        for blk in A.blocks(max(chunk_rows, 3 * ((A.shape[1] + 2) // 3))):
            R0 = update_r(R0, blk)
    else:
        for start in range(0, A.shape[0], chunk_rows):
            R0 = update_r(R0, A[start : start + chunk_rows])
    n = A.shape[1]
    if R0.shape[0] < n:  # fewer rows than columns: pad with zero rows
        R0 = np.vstack([R0, np.zeros((n - R0.shape[0], n))])
    return R0


def pivoted_cholesky(G: np.ndarray, n_steps: int | None = None):
    """Diagonal-pivoting Cholesky of a batch of Gram matrices (left-looking).

    G: (n, n) or (b, n, n) symmetric positive semidefinite.  At step k, with d the diagonal of
    the Schur complement (d_j = squared norm of column j's residual orthogonal to the k pivots
    chosen so far), pick p = argmax d (the QR pivot rule) and

        r_kk = sqrt(d_p),   R[k, :] = (G[p, :] - sum_{i<k} R[i, p] R[i, :]) / r_kk

    Returns (piv, Rrows): piv (b, n_steps) pivot indices, Rrows (b, n_steps, n) the rows of R
    indexed by ORIGINAL column (R in pivot order is Rrows[..., order]).  Pivots whose d_p is
    not positive get a zero row (rank-deficient G).
    """
    single = G.ndim == 2
    G = np.asarray(G, dtype=float)
    if single:
        G = G[None]
    b, n, _ = G.shape
    n_steps = n if n_steps is None else n_steps
    rows = np.arange(b)
    d = np.diagonal(G, axis1=1, axis2=2).copy()
    scale = np.maximum(d.max(axis=1), np.finfo(float).tiny)
    Rr = np.zeros((b, n_steps, n))
    piv = np.empty((b, n_steps), dtype=np.intp)
    tol = n * _EPS * scale
    for k in range(n_steps):
        p = np.argmax(d, axis=1)
        dp = d[rows, p]
        # Schur complement column p: G[p, :] - R[:k, p]^T R[:k, :]
        g = G[rows, p, :]
        if k:
            g = g - np.matmul(Rr[rows, :k, p][:, None, :], Rr[:, :k, :])[:, 0, :]
        ok = dp > tol  # zero pivot: rank exhausted
        if ok.all():
            row = g / np.sqrt(dp)[:, None]
        else:
            row = np.where(ok[:, None], g / np.sqrt(np.where(ok, dp, 1.0))[:, None], 0.0)
        Rr[:, k, :] = row
        d -= row * row
        d[rows, p] = -np.inf  # never pick again
        piv[:, k] = p
    if single:
        return piv[0], Rr[0]
    return piv, Rr


def _complete_order(piv: np.ndarray, n: int) -> np.ndarray:
    rest = np.setdiff1d(np.arange(n), piv, assume_unique=False)
    return np.concatenate([piv, rest]).astype(np.intp)


# --------------------------------------------------------------------------------------------
# the ranking
# --------------------------------------------------------------------------------------------


def _ranking(R, order, A_rows, labels, method, rtol, n_ranked=None, tail="zero"):
    """MarkerRanking from R (n x n or n_ranked x n, pivot order) and the pivot order.

    Only the first n_ranked pivots are ranked; the other rows of R are set to zero and their
    r to 0 (tail="zero": fewer rows than markers, they are exact combinations of the ranked)
    or NaN (tail="nan": not computed, beyond k_max).
    """
    n = len(labels)
    m = n if n_ranked is None else int(n_ranked)
    R = np.asarray(R, dtype=float)
    full = np.zeros((n, n))
    full[:m] = np.triu(R[:m, :n]) if R.shape[0] >= m else np.triu(np.vstack(
        [R[:, :n], np.zeros((m - R.shape[0], n))]))
    signs = np.where(np.diag(full) < 0, -1.0, 1.0)
    R = full * signs[:, None]  # fix the sign of each row: diag(R) >= 0
    r = np.abs(np.diag(R)).copy()
    if m < n and tail == "nan":
        r[m:] = np.nan
    order = np.asarray(order, dtype=np.intp)
    return MarkerRanking(
        order=order,
        labels_in_order=[labels[j] for j in order],
        R=R,
        r=r,
        r_rms=r / np.sqrt(A_rows),
        rows=int(A_rows),
        labels=list(labels),
        method=method,
        rtol=rtol,
        n_ranked=m,
    )


def _rest_in_original_order(order: np.ndarray, m: int, n: int | None = None) -> np.ndarray:
    """The first m pivots, then the other of the n columns in their original order."""
    head = np.asarray(order[:m], dtype=np.intp)
    n = len(order) if n is None else n
    return np.concatenate([head, np.setdiff1d(np.arange(n), head)]).astype(np.intp)


def _n_ranked(rows: int, n: int, k_max: int | None) -> int:
    return min(rows, n, n if k_max is None else int(k_max))


def rank_from_r0(R0: np.ndarray, rows: int, labels: Sequence[str],
                 k_max: int | None = None) -> MarkerRanking:
    """Pivoted QR (dgeqp3) of an n x n factor R0 with A^T A = R0^T R0 (e.g. from TSQR)."""
    R, order = scipy.linalg.qr(R0, mode="r", pivoting=True, check_finite=False)
    n = R0.shape[1]
    m = _n_ranked(rows, n, k_max)
    if m < n:  # R's rows beyond m refer to the old order: recompute R[:m] for the new one
        order = _rest_in_original_order(order, m)
        R = scipy.linalg.qr(R0[:, order], mode="r", check_finite=False)[0]
    return _ranking(R[:n], order, rows, labels, "tsqr", max(rows, n) * _EPS, m,
                    "zero" if m == min(rows, n) else "nan")


def rank_from_gram(G: np.ndarray, rows: int, labels: Sequence[str],
                   k_max: int | None = None) -> MarkerRanking:
    """Pivoted Cholesky of G = A^T A: G_PP = R^T R (the first min(rows, n, k_max) pivots)."""
    n = G.shape[0]
    m = _n_ranked(rows, n, k_max)
    # LAPACK's pivoted Cholesky (dpstrf: the pivot is the largest remaining Schur-complement
    # diagonal, i.e. the largest orthogonal residual, as in QR with column pivoting); it stops
    # at a numerically rank-deficient G, where our own implementation completes the order.
    if m == n:
        U, piv, rank, info = scipy.linalg.lapack.dpstrf(G, lower=0)
        if info == 0 and rank == n:
            order = piv - 1
            return _ranking(np.triu(U), order, rows, labels, "gram", np.sqrt(n * _EPS))
    piv, Rr = pivoted_cholesky(G, m)
    order = _complete_order(piv, n) if m == n else _rest_in_original_order(piv, m, n)
    # Gram accuracy: r_kk below ~sqrt(n eps) r_11 is noise
    return _ranking(Rr[:, order], order, rows, labels, "gram", np.sqrt(n * _EPS), m,
                    "zero" if m == min(rows, n) else "nan")


def rank_markers(A, labels: Sequence[str] | None = None, method: str = "auto", *,
                 k_max: int | None = None, threads: int | None = None,
                 seed: int = 0) -> MarkerRanking:
    """Rank markers by QR with column pivoting of A (3F x n, mm).  See the module docstring.

    k_max: rank only the first k_max pivots (default: all); threads: cores for the passes over
    A (default: what the caller allows, :func:`facemotion.gram.blas_threads`); seed: the
    randomized route's sketch.
    """
    A, labels = _unpack(A, labels)
    if method not in METHODS:
        raise InputError(f"method: unknown ranking method {method!r}; use one of {METHODS}")
    check_displacements(A, labels)
    rows, n = A.shape
    if k_max is not None and (isinstance(k_max, bool) or not isinstance(k_max, int | np.integer)
                              or k_max < 1):
        raise InputError(f"k_max: must be a positive integer, got {k_max!r}")
    m = _n_ranked(rows, n, k_max)
    if rows < n:
        log.warning("A has %d rows (%d frames) for %d markers: ranking the first %d pivots; "
                    "the other %d markers are exact combinations of them (r = 0, listed in "
                    "their original order)", rows, rows // 3, n, min(rows, n), n - rows)
    if method == "auto" and k_max is not None and n >= RANDOMIZED_MIN_N and m < n:
        method = "randomized"
        log.info("ranking route: randomized (n = %d markers >= %d, k_max = %d)", n,
                 RANDOMIZED_MIN_N, m)
    if method == "randomized":
        from facemotion.randomized_selection import rank_randomized

        if k_max is None:
            raise InputError("k_max: the randomized ranking needs k_max (pivots to choose)")
        return rank_randomized(A, labels, m, threads=threads, seed=seed)
    if method == "scipy":
        if _is_blocks(A):
            A = A.read()
        if not np.isfinite(A).all():
            _raise_nonfinite(A, labels)
        _check_column_norms(A, labels, np.einsum("ij,ij->j", A, A))
        R, order = scipy.linalg.qr(A, mode="r", pivoting=True, check_finite=False)
        if m < n:
            order = _rest_in_original_order(order, m)
            R = scipy.linalg.qr(A[:, order], mode="r", check_finite=False)[0]
        return _ranking(R[:n], order, rows, labels, "scipy", max(rows, n) * _EPS, m,
                        "zero" if m == min(rows, n) else "nan")
    if method in ("gram", "auto"):
        from facemotion.gram import gram

        G = gram(A, threads=threads)  # one pass (blocked syrk)
        _check_column_norms(A, labels, np.diag(G).copy())
        ranking = rank_from_gram(G, rows, labels, k_max)
        if method == "gram" or ranking.r[m - 1] >= GRAM_RATIO_LIMIT * ranking.r[0]:
            return ranking
    R0 = tsqr_r(A)
    if method == "tsqr":
        _check_column_norms(A, labels, np.einsum("ij,ij->j", R0, R0))
    return rank_from_r0(R0, rows, labels, k_max)


def ranking_summary(ranking: MarkerRanking, zero_rows: int = 0) -> dict:
    """What the ranking could and did rank, for the rank table and the log: rows of A, the
    rows that are exactly zero (each sentence's neutral frame when displacements are taken
    from the first frame), markers, pivots chosen by the QR rule, the numerical rank, the
    route, and a note when A has fewer independent rows than markers or the ranking stops at
    k_max."""
    rows, n, m = ranking.rows, ranking.n, ranking.n_ranked
    live = rows - int(zero_rows)
    note = ""
    if live < n:
        note = (f"fewer rows than markers: A has {rows} rows"
                + (f" ({zero_rows} of them zero: the neutral frames)" if zero_rows else "")
                + f" for {n} markers, so at most {live} markers are independent; the QR rule "
                f"ranked {m} pivots (numerical rank {ranking.numerical_rank()}), the other "
                f"{n - m} markers are exact combinations of them (r = 0, original order)")
    elif m < n:
        note = (f"ranking stops at k_max = {m} of {n} markers ({ranking.method} route): later "
                "r values, the epsilon-rank and ||R22|| are not computed")
    return {"rows": rows, "zero_rows": int(zero_rows), "markers": n, "pivots_ranked": m,
            "numerical_rank": ranking.numerical_rank(), "route": ranking.method,
            "note": note}


def study_route(n: int, method: str = "auto", k_max: int | None = None) -> tuple[str, str]:
    """The route the study ranks ``n`` markers by, and why (for the log).

    'auto' takes the randomized route from ``RANDOMIZED_MIN_N`` markers on when ``k_max`` is
    set (the first k_max pivots from a sketch: two passes of O(rows n k_max) flops instead of
    the Gram's O(rows n^2)); otherwise every pivot, by the Gram route (TSQR when the Gram
    matrix is not accurate enough). A method other than 'auto' is taken as given.
    """
    if method not in METHODS:
        raise InputError(f"setting qr.method: unknown ranking method {method!r}; use one of "
                         f"{', '.join(METHODS)}")
    if method == "randomized":
        if k_max is None:
            raise InputError("setting qr.k_max: the randomized route needs k_max (how many "
                             "pivots to choose)")
        return "randomized", f"qr.method 'randomized', first k_max = {k_max} pivots"
    if method != "auto":
        return method, f"qr.method {method!r}, every pivot"
    if k_max is not None and n >= RANDOMIZED_MIN_N:
        return "randomized", (f"qr.method 'auto': {n} markers >= {RANDOMIZED_MIN_N} with "
                              f"qr.k_max = {k_max}: the first {k_max} pivots from a sketch")
    why = (f"{n} markers < {RANDOMIZED_MIN_N}" if n < RANDOMIZED_MIN_N
           else "qr.k_max not set")
    return "auto", f"qr.method 'auto' ({why}): every pivot by the Gram route (TSQR fallback)"


def rank_for_study(A, labels: Sequence[str] | None = None, method: str = "auto", *,
                   k_max: int | None = None, threads: int | None = None,
                   seed: int = 0) -> MarkerRanking:
    """The ranking every stage of the study uses (:func:`study_route` picks the route, and it
    is logged): all n pivots (so every r_kk and the epsilon-rank are known) unless the route
    is the randomized one, which ranks the first ``k_max``. ``k_max`` itself bounds the error
    curves (:func:`facemotion.prediction.error_curve`), not this ranking."""
    A, labels = _unpack(A, labels)
    n = A.shape[1]
    route, why = study_route(n, method, k_max)
    ranking = rank_markers(A, labels, method=route, k_max=k_max if route == "randomized"
                           else None, threads=threads, seed=seed)
    log.info("ranking route: %s (%s); ranked %d of %d markers by %s", route, why,
             ranking.n_ranked, n, ranking.method)
    return ranking


def route_accuracy(A, ranking: MarkerRanking, *, threads: int | None = None) -> dict:
    """How close the randomized route's selection is to deterministic pivoted QR (issue 12:
    within 1.05x): ||A - A_S X||_F of the ranking's first k columns over that of the Gram
    route's (pivoted QR's pivots, exactly) at the same k, for k in 10, 50, 100 and k_max (those
    not beyond k_max). Costs the Gram pass the randomized route avoids; logged. Returns
    {"k": [...], "ratio": [...]} (empty lists for a ranking that is not randomized)."""
    from facemotion.randomized_selection import selection_residual

    if ranking.method != "randomized":
        return {"k": [], "ratio": []}
    A, labels = _unpack(A, ranking.labels)
    det = rank_markers(A, labels, method="gram", threads=threads)
    m = ranking.n_ranked
    ks = sorted({k for k in (10, 50, 100, m) if k <= m})
    ratios = [selection_residual(A, ranking.order, k) / selection_residual(A, det.order, k)
              for k in ks]
    log.info("randomized route vs deterministic pivoted QR (Gram route), residual "
             "||A - A_S X||_F ratio at k = %s: %s (issue 12 asks <= 1.05)", ks,
             ", ".join(f"{r:.4f}" for r in ratios))
    return {"k": ks, "ratio": ratios}


def spectral_norm(M: np.ndarray) -> float:
    """||M||_2, the largest singular value (0 for an empty matrix)."""
    if M.size == 0:
        return 0.0
    return float(scipy.linalg.svdvals(M, check_finite=False)[0])


def r22_norm(ranking: MarkerRanking, k: int) -> float:
    """||R22||_2 with R22 = R[k:, k:] (eq. 1), unnormalised (mm); 0 for k = n."""
    if not 0 <= k <= ranking.n:
        raise InputError(f"k: {k} is outside 0 <= k <= n = {ranking.n}")
    return spectral_norm(ranking.R[k:, k:])


def paper_epsilon_rank(ranking: MarkerRanking, epsilon: float,
                       normalisation: str = DEFAULT_R_NORMALISATION) -> tuple[int, float]:
    """The smallest k with ||R22||_2 <= epsilon (Sec. III), R under ``normalisation``.

    Bisection over k: ||R[k:, k:]||_2 is non-increasing in k (a submatrix of the previous
    block), so about log2(n + 1) 2-norms are computed.  Returns (k, ||R22||_2 at k), the norm
    in the normalisation's units.
    """
    scale = r_scale(ranking.rows, normalisation)
    lo, hi = 0, ranking.n                       # ||R[n:, n:]||_2 = 0 <= epsilon
    norm_hi = 0.0
    while lo < hi:
        mid = (lo + hi) // 2
        v = spectral_norm(ranking.R[mid:, mid:]) / scale
        if v <= epsilon:
            hi, norm_hi = mid, v
        else:
            lo = mid + 1
    return lo, norm_hi


RANK_COLUMNS = ["tolerance_mm", "r_normalisation", "epsilon_rank", "r22_norm_at_rank_mm",
                "diagonal_count", "redundant_markers"]


def epsilon_rank(ranking: MarkerRanking, tolerances_mm,
                 normalisation: str = DEFAULT_R_NORMALISATION) -> pd.DataFrame:
    """Epsilon-rank for each tolerance epsilon (mm), R under ``normalisation``.

    Columns: ``epsilon_rank``, the paper's rule (smallest k with ||R22||_2 <= epsilon, Sec. III);
    ``r22_norm_at_rank_mm``, ||R22||_2 at that k; ``diagonal_count``, the number of pivots with
    normalised |r_kk| > epsilon (an older, looser reading, never larger); ``redundant_markers``,
    the markers after the epsilon-rank in pivot order (comma-separated labels). A ranking
    that stops at k_max (the randomized route) leaves epsilon_rank and ||R22||_2 unknown (NaN,
    no redundant markers listed); its diagonal count over the ranked pivots is then a lower
    bound of the epsilon-rank.
    """
    try:
        tols = np.atleast_1d(np.asarray(tolerances_mm, dtype=float)).ravel()
    except (TypeError, ValueError) as exc:
        raise InputError(f"tolerances_mm: not a list of numbers ({exc})") from None
    bad = tols[~(np.isfinite(tols) & (tols > 0))]
    if bad.size:
        raise InputError(f"tolerances_mm: tolerances must be positive finite mm, got "
                         f"{float(bad[0])}")
    r = ranking.normalised_r(normalisation)
    out = []
    stops = bool(np.isnan(ranking.r).any())  # the randomized route: first k_max pivots only
    for tol in tols:
        if stops:
            # ||R22||_2 is not known past k_max; |r_kk| <= ||R[j:, j:]||_2 for j <= k, so the
            # pivots above epsilon still bound the epsilon-rank from below
            m = ranking.n_ranked
            out.append({"tolerance_mm": float(tol), "r_normalisation": normalisation,
                        "epsilon_rank": np.nan, "r22_norm_at_rank_mm": np.nan,
                        "diagonal_count": int(np.count_nonzero(r[:m] > tol)),
                        "redundant_markers": ""})
            continue
        k, norm = paper_epsilon_rank(ranking, float(tol), normalisation)
        out.append(
            {
                "tolerance_mm": float(tol),
                "r_normalisation": normalisation,
                "epsilon_rank": k,
                "r22_norm_at_rank_mm": norm,
                "diagonal_count": int(np.count_nonzero(r > tol)),
                "redundant_markers": ",".join(ranking.labels_in_order[k:]),
            }
        )
    return pd.DataFrame(out, columns=RANK_COLUMNS)
