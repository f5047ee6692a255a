"""Pivoted QR of A from one pass over it: TSQR's R0, or the Gram matrix's pivoted Cholesky.

See :mod:`facemotion.ranking` for the routes and their accuracy."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from facemotion.ranking.result import (
    EPS,
    MarkerRanking,
    complete_order,
    is_row_blocks,
    make_ranking,
    n_ranked_for,
    rest_in_original_order,
)

#: Auto route: use the Gram matrix only while every r_kk / r_11 is above this ratio.
GRAM_RATIO_LIMIT = 1e-4


#: Rows per block of the streaming TSQR pass (a multiple of 3: whole frames).
CHUNK_ROWS = 3 * 4096



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
    if is_row_blocks(A):
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
    tol = n * EPS * scale
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


def rank_from_r0(R0: np.ndarray, rows: int, labels: Sequence[str],
                 k_max: int | None = None) -> MarkerRanking:
    """Pivoted QR (dgeqp3) of an n x n factor R0 with A^T A = R0^T R0 (e.g. from TSQR)."""
    R, order = scipy.linalg.qr(R0, mode="r", pivoting=True, check_finite=False)
    n = R0.shape[1]
    m = n_ranked_for(rows, n, k_max)
    if m < n:  # R's rows beyond m refer to the old order: recompute R[:m] for the new one
        order = rest_in_original_order(order, m)
        R = scipy.linalg.qr(R0[:, order], mode="r", check_finite=False)[0]
    return make_ranking(R[:n], order, rows, labels, "tsqr", max(rows, n) * EPS, m,
                    "zero" if m == min(rows, n) else "nan")


def rank_from_gram(G: np.ndarray, rows: int, labels: Sequence[str],
                   k_max: int | None = None) -> MarkerRanking:
    """Pivoted Cholesky of G = A^T A: G_PP = R^T R (the first min(rows, n, k_max) pivots)."""
    n = G.shape[0]
    m = n_ranked_for(rows, n, k_max)
    # LAPACK's pivoted Cholesky (dpstrf: the pivot is the largest remaining Schur-complement
    # diagonal, i.e. the largest orthogonal residual, as in QR with column pivoting); it stops
    # at a numerically rank-deficient G, where our own implementation completes the order.
    if m == n:
        U, piv, rank, info = scipy.linalg.lapack.dpstrf(G, lower=0)
        if info == 0 and rank == n:
            order = piv - 1
            return make_ranking(np.triu(U), order, rows, labels, "gram", np.sqrt(n * EPS))
    piv, Rr = pivoted_cholesky(G, m)
    order = complete_order(piv, n) if m == n else rest_in_original_order(piv, m, n)
    # Gram accuracy: r_kk below ~sqrt(n eps) r_11 is noise
    return make_ranking(Rr[:, order], order, rows, labels, "gram", np.sqrt(n * EPS), m,
                    "zero" if m == min(rows, n) else "nan")
