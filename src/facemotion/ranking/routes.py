"""Which route ranks the markers, and the ranking the study uses.

:func:`rank_markers` is QR with column pivoting of A by one of the routes described in
:mod:`facemotion.ranking` (``METHODS``); :func:`rank_for_study` picks the route for the study
(:func:`study_route`) and logs why; :func:`route_accuracy` compares the randomized route's
selection with pivoted QR's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from facemotion.errors import InputError
from facemotion.ranking.qr import EPS, GRAM_RATIO_LIMIT, rank_from_gram, rank_from_r0, tsqr_r
from facemotion.ranking.result import (
    MarkerRanking,
    as_matrix,
    check_column_norms,
    check_displacements,
    is_row_blocks,
    log,
    make_ranking,
    n_ranked_for,
    raise_nonfinite,
    rest_in_original_order,
)

#: Auto route: the randomized selection from this many markers on (when k_max is set).
RANDOMIZED_MIN_N = 2000


METHODS = ("auto", "gram", "tsqr", "scipy", "randomized")


def rank_markers(A, labels: Sequence[str] | None = None, method: str = "auto", *,
                 k_max: int | None = None, threads: int | None = None,
                 seed: int = 0) -> MarkerRanking:
    """Rank markers by QR with column pivoting of A (3F x n, mm).  See the module docstring.

    k_max: rank only the first k_max pivots (default: all); threads: cores for the passes over
    A (default: what the caller allows, :func:`facemotion.ranking.gram.blas_threads`); seed: the
    randomized route's sketch.
    """
    A, labels = as_matrix(A, labels)
    if method not in METHODS:
        raise InputError(f"method: unknown ranking method {method!r}; use one of {METHODS}")
    check_displacements(A, labels)
    rows, n = A.shape
    if k_max is not None and (isinstance(k_max, bool) or not isinstance(k_max, int | np.integer)
                              or k_max < 1):
        raise InputError(f"k_max: must be a positive integer, got {k_max!r}")
    m = n_ranked_for(rows, n, k_max)
    if rows < n:
        log.warning("A has %d rows (%d frames) for %d markers: ranking the first %d pivots; "
                    "the other %d markers are exact combinations of them (r = 0, listed in "
                    "their original order)", rows, rows // 3, n, min(rows, n), n - rows)
    if method == "auto" and k_max is not None and n >= RANDOMIZED_MIN_N and m < n:
        method = "randomized"
        log.info("ranking route: randomized (n = %d markers >= %d, k_max = %d)", n,
                 RANDOMIZED_MIN_N, m)
    if method == "randomized":
        from facemotion.ranking.randomized import rank_randomized

        if k_max is None:
            raise InputError("k_max: the randomized ranking needs k_max (pivots to choose)")
        return rank_randomized(A, labels, m, threads=threads, seed=seed)
    if method == "scipy":
        if is_row_blocks(A):
            A = A.read()
        if not np.isfinite(A).all():
            raise_nonfinite(A, labels)
        check_column_norms(A, labels, np.einsum("ij,ij->j", A, A))
        R, order = scipy.linalg.qr(A, mode="r", pivoting=True, check_finite=False)
        if m < n:
            order = rest_in_original_order(order, m)
            R = scipy.linalg.qr(A[:, order], mode="r", check_finite=False)[0]
        return make_ranking(R[:n], order, rows, labels, "scipy", max(rows, n) * EPS, m,
                        "zero" if m == min(rows, n) else "nan")
    if method in ("gram", "auto"):
        from facemotion.ranking.gram import gram

        G = gram(A, threads=threads)  # one pass (blocked syrk)
        check_column_norms(A, labels, np.diag(G).copy())
        ranking = rank_from_gram(G, rows, labels, k_max)
        if method == "gram" or ranking.r[m - 1] >= GRAM_RATIO_LIMIT * ranking.r[0]:
            return ranking
    R0 = tsqr_r(A)
    if method == "tsqr":
        check_column_norms(A, labels, np.einsum("ij,ij->j", R0, R0))
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
        raise InputError(f"method: unknown ranking method {method!r}; use one of "
                         f"{', '.join(METHODS)}")
    if method == "randomized":
        if k_max is None:
            raise InputError("k_max: the randomized route needs k_max (how many "
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
    curves (:func:`facemotion.regions.prediction.error_curve`), not this ranking."""
    A, labels = as_matrix(A, labels)
    n = A.shape[1]
    route, why = study_route(n, method, k_max)
    ranking = rank_markers(A, labels, method=route, k_max=k_max if route == "randomized"
                           else None, threads=threads, seed=seed)
    log.info("ranking route: %s (%s); ranked %d of %d markers by %s", route, why,
             ranking.n_ranked, n, ranking.method)
    return ranking


def route_accuracy(A, ranking: MarkerRanking, *, threads: int | None = None) -> dict:
    """How close the randomized route's selection is to deterministic pivoted QR (1 when it
    found the same subspace): ||A - A_S X||_F of the ranking's first k columns over that of the Gram
    route's (pivoted QR's pivots, exactly) at the same k, for k in 10, 50, 100 and k_max (those
    not beyond k_max). Costs the Gram pass the randomized route avoids; logged. Returns
    {"k": [...], "ratio": [...]} (empty lists for a ranking that is not randomized)."""
    from facemotion.ranking.randomized import selection_residual

    if ranking.method != "randomized":
        return {"k": [], "ratio": []}
    A, labels = as_matrix(A, ranking.labels)
    det = rank_markers(A, labels, method="gram", threads=threads)
    m = ranking.n_ranked
    ks = sorted({k for k in (10, 50, 100, m) if k <= m})
    ratios = [selection_residual(A, ranking.order, k) / selection_residual(A, det.order, k)
              for k in ks]
    log.info("randomized route vs deterministic pivoted QR (Gram route), residual "
             "||A - A_S X||_F ratio at k = %s: %s (1: the same subspace)", ks,
             ", ".join(f"{r:.4f}" for r in ratios))
    return {"k": ks, "ratio": ratios}
