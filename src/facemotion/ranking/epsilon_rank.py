"""The epsilon-rank (Lucero & Munhall 2008, Sec. III, eq. 1) from R.

Partition R after k pivots, R22 = R[k:, k:]; the epsilon-rank is the smallest k with
||R22||_2 <= epsilon, which bounds the singular values sigma_{k+1}(A) <= ||R22||_2 (Chan 1987).
Since R[k+1:, k+1:] is a submatrix of R[k:, k:], ||R22||_2 is non-increasing in k and a
bisection needs only O(log n) 2-norms. The older count of diagonal entries above epsilon is
kept beside it (``diagonal_count``); it is never larger than the epsilon-rank, because
|r_jj| <= ||R[k:, k:]||_2 for every k <= j.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.linalg.lapack

from facemotion.errors import InputError
from facemotion.ranking.result import (
    ASKED,
    DEFAULT_R_NORMALISATION,
    MarkerRanking,
    r_scale,
)


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


def noise_epsilon(sigma_mm: float, rows: int, n: int,
                  normalisation: str = DEFAULT_R_NORMALISATION) -> float:
    """The tolerance at the measurement noise: the expected 2-norm of a rows x n matrix of white
    noise with ``sigma_mm`` per coordinate, sigma (sqrt(rows) + sqrt(n)) (the largest singular
    value of a Gaussian matrix, Gordon's bound), in ``normalisation``'s units.  A remainder
    R22 below it is no larger than the noise alone would be."""
    if not (np.isfinite(sigma_mm) and sigma_mm > 0):
        raise InputError(f"noise level: must be a positive number of mm, got {sigma_mm!r}")
    return float(sigma_mm) * (np.sqrt(rows) + np.sqrt(n)) / r_scale(rows, normalisation)


#: ``remainder_norms`` computes every ||R[k:, k:]||_2 up to this many markers (n SVDs of up
#: to n x n: O(n^4)); beyond, NaN.
REMAINDER_NORMS_MAX_N = 128


def remainder_norms(ranking: MarkerRanking) -> np.ndarray:
    """||R[k:, k:]||_2 for k = 0..n-1 (unnormalised mm; the remainder before pivot k + 1),
    NaN when n exceeds REMAINDER_NORMS_MAX_N or R is not complete (randomized route)."""
    n = ranking.n
    if n > REMAINDER_NORMS_MAX_N or not np.isfinite(ranking.R).all():
        return np.full(n, np.nan)
    return np.array([spectral_norm(ranking.R[k:, k:]) for k in range(n)])


def singular_values(ranking: MarkerRanking) -> np.ndarray:
    """The singular values of A, largest first: those of R (A P = Q R, Q orthonormal); NaN
    when R is not complete."""
    if not np.isfinite(ranking.R).all():
        return np.full(ranking.n, np.nan)
    return scipy.linalg.svdvals(ranking.R, check_finite=False)


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


def epsilon_rank_table(ranking: MarkerRanking, tolerances_mm, normalisation: str,
                       facts: dict | None = None, extra: dict | None = None) -> pd.DataFrame:
    """The rank table of a dataset (``rank.tsv``): :func:`epsilon_rank` at ``tolerances_mm``
    and at each tolerance of ``extra`` (tolerance -> why) that they do not list, with where
    each tolerance comes from (``tolerance_from``) and the ranking's ``facts`` (rows, markers,
    route, ...) in every row, before the redundant markers."""
    asked = [float(t) for t in tolerances_mm]
    added = {float(t): why for t, why in (extra or {}).items()
             if not np.any(np.isclose(asked, float(t)))}
    table = epsilon_rank(ranking, asked + list(added), normalisation=normalisation)
    table.insert(1, "tolerance_from", [ASKED] * len(asked) + list(added.values()))
    for key, value in (facts or {}).items():
        table.insert(len(table.columns) - 1, key, value)
    return table
