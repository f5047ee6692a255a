"""Choosing the first k of many markers from a sketch of A, refined on A itself.

With thousands of columns the Gram pass costs rows x n^2 flops. The first k pivots need far
less (Halko, Martinsson & Tropp 2011, SIAM Rev. 53:217; Duersch & Gu 2017, SIAM J. Sci.
Comput. 39:C263, randomized QR with column pivoting):

1. Sketch: Y = Omega A, with Omega an l x rows Gaussian matrix (one pass over A, 2 l rows n
   flops, which also gives every column's norm). Y's columns keep the geometry of A's columns
   up to a small distortion, so QR with column pivoting of Y (LAPACK dgeqp3, l x n) points at
   the columns that pivoted QR of A would take.
2. Refinement on A: for candidate columns C, one pass gives W = A_C^T A (c x n), whose
   columns C are the exact Gram matrix G_CC. Pivoted Cholesky on the candidates' residual
   cross products repeats the QR pivot rule with A's exact residuals and yields the rows of
   R for the chosen pivots over all n columns: R[i, :] = (W_p - R[:i, p]^T R[:i, :]) / r_ii
   (G_SS = R_SS^T R_SS, R12 = Q1^T A_s). So X = R11^-1 R12, the error curves and the training
   residual ||A - A_S X||_F^2 = ||A||_F^2 - sum_i ||R[i, :]||^2 are exact for the chosen S.
   Refinement goes on in rounds of b pivots (k / ``ROUNDS``, at least ``BLOCK_MIN``), each
   with a fresh sketch of the residual, Omega (A - Q_S Q_S^T A) = Y - (Y_S R_SS^-1) R[:k, :]
   (no pass over A: Duersch & Gu's sample update), and one pass for W of its candidates: the
   c best columns of that sketch plus the c columns with the largest exact residual (known
   for every column from R[:k, :]). In the first ``MAX_EXACT_ROUNDS`` rounds a pivot is taken
   only where it is exactly pivoted QR's (the column of largest residual is a candidate); a
   round ends when it is not, and the next round fetches it. Later rounds take the candidate
   with the largest residual.

Cost: the sketch pass plus one pass per round (about ROUNDS to 2 ROUNDS passes), 2 rows n
(l + 2 c rounds) flops in all (c = 2 b candidates of each kind), against rows n^2 for the Gram
pass: worth it from ~2,000 markers (benchmarks/bench_dense.py measures both).

Accuracy (tests/test_randomized_selection.py): on dense low-rank-plus-noise matrices the
residual ||A - A_S X||_F is within 1.05 x that of deterministic pivoted QR at k = 10, 50 and
100 (measured 0.98-1.04 on three matrices of 2,000 columns). Every call logs its sketch, its
rounds, how many pivots followed the exact QR rule and its residuals at a few k.
"""

from __future__ import annotations

import logging

import numpy as np

from facemotion.errors import InputError

#: Sketch rows beyond the candidates of a round.
OVERSAMPLE = 10
#: Candidates (from the sketch) per pivot chosen (on A) in a round.
CANDIDATES_PER_PIVOT = 2
#: The k pivots are chosen in about this many rounds (passes over A) ...
ROUNDS = 4
#: ... of at least this many pivots each.
BLOCK_MIN = 10
#: Rounds that follow pivoted QR exactly (a round ends when QR's next pivot is not among
#: its candidates); later rounds take the best candidate.
MAX_EXACT_ROUNDS = ROUNDS
log = logging.getLogger("facemotion")


def _blocks(A, block_rows=None):
    from facemotion.ranking.gram import _blocks_rows

    if isinstance(A, np.ndarray):
        step = block_rows or _blocks_rows(A.shape[1], 16 * 2**20)
        start = 0
        for a in range(0, A.shape[0], step):
            yield start, A[a:a + step]
            start += min(step, A.shape[0] - a)
    else:
        start = 0
        for blk in A.blocks(block_rows):
            yield start, blk
            start += blk.shape[0]


def gaussian_sketch(A, l: int, seed: int = 0, threads: int | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Y = Omega A (l x n) and the squared column norms of A, in one pass over row blocks.

    Omega's entries are N(0, 1/l), drawn for each block from a generator seeded with
    (seed, first row of the block): the same A, block size and seed give the same Y.
    """
    from threadpoolctl import threadpool_limits

    from facemotion.ranking.gram import blas_threads

    n = A.shape[1]
    Y = np.zeros((l, n))
    sq = np.zeros(n)
    with threadpool_limits(blas_threads() if threads is None else threads, user_api="blas"):
        for start, blk in _blocks(A):
            Om = np.random.default_rng([seed, start]).standard_normal((l, blk.shape[0]))
            Y += Om @ blk
            sq += np.einsum("ij,ij->j", blk, blk)
    Y /= np.sqrt(l)
    return Y, sq


def candidate_products(A, cols, threads: int | None = None) -> np.ndarray:
    """W = A_C^T A (c x n) in one pass over row blocks."""
    from threadpoolctl import threadpool_limits

    from facemotion.ranking.gram import blas_threads

    cols = np.asarray(cols, dtype=np.intp)
    W = np.zeros((cols.size, A.shape[1]))
    with threadpool_limits(blas_threads() if threads is None else threads, user_api="blas"):
        for _, blk in _blocks(A):
            W += blk[:, cols].T @ blk
    return W


def _cholesky_rows(E: np.ndarray, cand: np.ndarray, b: int, res: np.ndarray, exact: bool
                   ) -> tuple[np.ndarray, np.ndarray, int]:
    """Up to b steps of left-looking pivoted Cholesky on residual cross products
    E = (A_C^T A)_res (c x n; column cand[i] of E is candidate i's own column).

    res (n,): every column's squared residual norm, updated in place. The QR rule picks the
    column with the largest residual among ALL columns; while that column is a candidate the
    step is exactly pivoted QR's. When it is not: with ``exact`` the round stops (the next
    pass fetches it), else the largest-residual candidate is taken. The new row is
    R[i, :] = (E[p, :] - R[:i, cand[p]]^T R[:i, :]) / sqrt(d_p).
    Returns the pivots (indices into cand), the new rows of R (over all n columns) and how
    many steps followed the exact rule.
    """
    c, n = E.shape
    pos = {int(j): i for i, j in enumerate(cand)}
    Rn = np.zeros((b, n))
    piv = []
    n_exact = 0
    d_c = res[cand].copy()
    for i in range(b):
        top = int(np.argmax(res))
        if top in pos and not np.isneginf(d_c[pos[top]]):
            p = pos[top]
            n_exact += 1
        elif exact and i > 0:
            break
        else:
            p = int(np.argmax(d_c))
        if not d_c[p] > 0:
            break
        row = E[p] - Rn[:i, cand[p]] @ Rn[:i]
        Rn[i] = row / np.sqrt(d_c[p])
        res -= Rn[i] ** 2
        d_c = res[cand].copy()
        for q in piv + [p]:
            d_c[q] = -np.inf
        res[cand[p]] = -np.inf  # never pick again
        piv.append(p)
    return np.asarray(piv, dtype=np.intp), Rn[:len(piv)], n_exact


def rank_randomized(A, labels, k: int, *, threads: int | None = None, seed: int = 0,
                    oversample: int = OVERSAMPLE):
    """MarkerRanking with the first k pivots chosen from a sketch and refined on A.

    R holds the first k rows of A's R in pivot order (exact for the chosen pivots); later rows
    are zero and r = NaN there; the other markers follow by decreasing residual norm.
    """
    import scipy.linalg

    from facemotion.ranking.result import check_column_norms, make_ranking

    rows, n = A.shape
    k = int(min(k, rows, n))
    b = min(k, max(BLOCK_MIN, -(-k // ROUNDS)))           # pivots per round
    c = min(CANDIDATES_PER_PIVOT * b, n)                  # candidates per round, per kind
    l_ = min(c + oversample, n)
    Y, sq = gaussian_sketch(A, l_, seed=seed, threads=threads)
    check_column_norms(A, labels, sq)
    S = np.zeros(0, dtype=np.intp)
    Rk = np.zeros((0, n))                                 # rows of R so far (original columns)
    res = sq.copy()                                       # squared residual norms, all columns
    rounds = n_exact = 0
    while S.size < k:
        # sketch of the residual: Omega (A - Q_S Q_S^T A) = Y - (Y_S R_SS^-1) R[:k, :]
        Yr = Y
        if S.size:
            OmQ = scipy.linalg.solve_triangular(Rk[:, S], Y[:, S].T, trans="T").T
            Yr = Y - OmQ @ Rk
        _, piv_y = scipy.linalg.qr(Yr, mode="r", pivoting=True, check_finite=False)
        chosen = set(S.tolist())
        from_sketch = [int(j) for j in piv_y if j not in chosen][:c]
        by_residual = [int(j) for j in np.argsort(-res, kind="stable")[:c] if j not in chosen]
        cand = np.array(list(dict.fromkeys(by_residual + from_sketch)), dtype=np.intp)
        W = candidate_products(A, cand, threads=threads)  # A_C^T A (one pass)
        E = W - Rk[:, cand].T @ Rk                        # residual cross products
        piv, Rn, ex = _cholesky_rows(E, cand, min(b, k - S.size), res,
                                     exact=rounds < MAX_EXACT_ROUNDS)
        if piv.size == 0:
            raise InputError("A: the randomized ranking found fewer than k_max independent "
                             "markers; use a smaller k_max or the 'gram' route")
        S = np.concatenate([S, cand[piv]])
        Rk = np.vstack([Rk, Rn])
        rounds += 1
        n_exact += ex
    resid = np.maximum(sq - np.einsum("ij,ij->j", Rk, Rk), 0.0)  # residual column norms^2
    rest = np.setdiff1d(np.arange(n), S)
    rest = rest[np.argsort(-resid[rest], kind="stable")]
    order = np.concatenate([S, rest]).astype(np.intp)
    ranking = make_ranking(Rk[:, order], order, rows, labels, "randomized",
                       np.sqrt(n * np.finfo(float).eps), k, "nan")
    total = float(sq.sum())
    tail = total - np.cumsum(np.einsum("ij,ij->i", Rk, Rk))
    ks = sorted({kk for kk in (1, 10, 50, 100, k) if kk <= k})
    log.info("randomized ranking: %d markers, %d rows, k_max = %d: Gaussian sketch of %d rows "
             "(seed %d), %d rounds of up to %d pivots from up to %d candidates (%d passes over "
             "A); %d of %d pivots by the exact QR rule; training residual "
             "||A - A_S X||_F / ||A||_F at k = %s: %s", n, rows, k, l_, seed, rounds, b,
             2 * c, rounds + 1, n_exact, k, ks,
             ", ".join(f"{np.sqrt(max(tail[kk - 1], 0.0) / total):.4g}" for kk in ks))
    return ranking


def selection_residual(A, order, k: int) -> float:
    """||A - A_S X||_F for the first k columns of ``order`` (X the least-squares fit), from
    one pass: ||A||_F^2 - ||R_SS^-T A_S^T A||_F^2. The reference measure of a selection."""
    import scipy.linalg

    S = np.asarray(order[:k], dtype=np.intp)
    W = candidate_products(A, S)
    R = np.linalg.cholesky(W[:, S]).T  # G_SS = R^T R
    Z = scipy.linalg.solve_triangular(R, W, trans="T")
    total = 0.0
    for _, blk in _blocks(A):
        total += float(np.einsum("ij,ij->", blk, blk))
    return float(np.sqrt(max(total - np.einsum("ij,ij->", Z, Z), 0.0)))
