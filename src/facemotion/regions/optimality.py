"""How good is the QR marker subset?  QR vs exhaustive vs greedy column subset selection.

For a subset S of k markers the prediction residual is the projection residual

    res(S)^2 = ||A - A_S A_S^+ A||_F^2 = tr(G) - tr(G_SS^-1 (G^2)_SS),    G = A^T A

(the explained part is sum_j g_Sj^T G_SS^-1 g_Sj = tr(G_SS^-1 G_S: G_:S)).  All three methods
work on G only (one pass over A):

* QR: the first k pivots; res = ||R22||_F.
* greedy forward selection: add the marker with the largest gain ||G'_:p||^2 / G'_pp, where G'
  is the Schur complement of G in the chosen set (the residual Gram matrix).
* exhaustive: every subset.  For k >= 2 the subsets are enumerated as a prefix T of k - 2
  markers plus a pair {p, q} with max(T) < p < q: with G' = G - G_:T G_TT^-1 G_T: (batched over
  prefixes) and H' = G'^2, the gain of the pair is the 2 x 2 trace formula

      gain(p, q) = (G'_qq H'_pp + G'_pp H'_qq - 2 G'_pq H'_pq) / (G'_pp G'_qq - G'_pq^2)

  evaluated for all pairs at once.  Cost ~ C(n, k-2) (n - max T)^2 n, so k = 5 of 57 markers
  (4.2 million subsets) takes seconds.  When C(n, k) exceeds ``max_subsets`` the exhaustive
  columns say "not computed" / NaN and a warning is issued.

RMS: residual_rms_mm = res / sqrt(rows (n - k)), the RMS over the secondary-marker coordinates
(like ``prediction.error_curve``'s rms_error_mm on training data).  The optimal subset's residual
is recomputed from A by least squares, so rounding in the trace formula cannot bias the ratio.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.ranking.result import as_matrix
from facemotion.ranking.routes import rank_markers

COLUMNS = [
    "k",
    "qr_subset",
    "qr_residual_rms_mm",
    "optimal_subset",
    "optimal_residual_rms_mm",
    "greedy_subset",
    "greedy_residual_rms_mm",
    "qr_over_optimal",
]
NOT_COMPUTED = "not computed"


def projection_residual(A: np.ndarray, subset: Sequence[int]) -> float:
    """||A - A_S A_S^+ A||_F, A's part orthogonal to the span of the subset's columns.

    From a Householder QR of A_S = Q R (backward stable, like least squares): the residual is
    A - Q (Q^T A).  When A_S is numerically rank-deficient (its singular values, those of R,
    below least squares' default cutoff eps max(m, k) s_max), by least squares (SVD), which
    drops the dependent directions."""
    S = list(subset)
    As = A[:, S]
    Q, R = np.linalg.qr(As)
    s = np.linalg.svd(R, compute_uv=False)
    if s.size and s[-1] > np.finfo(float).eps * max(As.shape) * s[0]:
        return float(np.linalg.norm(A - Q @ (Q.T @ A)))
    X = np.linalg.lstsq(As, A, rcond=None)[0]
    return float(np.linalg.norm(A - As @ X))


def _schur(G, T):
    """Residual Gram matrix G' = G - G_:T G_TT^-1 G_T: (Schur complement)."""
    if not T:
        return G.copy()
    T = list(T)
    L = np.linalg.cholesky(G[np.ix_(T, T)])
    W = np.linalg.solve(L, G[T, :])  # L^-1 G_T:
    return G - W.T @ W


def greedy_subset(G: np.ndarray, k: int, force: Sequence[int] = (),
                  exclude: Sequence[int] = ()) -> list[int]:
    """Forward selection: each step adds the marker with the largest drop in residual.

    ``force``: column indices chosen first (greedily among themselves); ``exclude``: columns
    never chosen."""
    Gp = G.copy()
    chosen: list[int] = []
    force, barred = [int(j) for j in force], [int(j) for j in exclude]
    for step in range(k):
        d = np.diag(Gp).copy()
        with np.errstate(divide="ignore", invalid="ignore"):
            gain = np.where(d > 1e-12 * np.trace(G), (Gp * Gp).sum(axis=0) / d, -np.inf)
        gain[chosen] = -np.inf
        gain[barred] = -np.inf
        if step < len(force):
            gain[[j for j in range(G.shape[0]) if j not in force]] = -np.inf
        p = int(np.argmax(gain))
        chosen.append(p)
        col = Gp[:, p] / np.sqrt(Gp[p, p])
        Gp = Gp - np.outer(col, col)  # Schur complement after adding p
    return chosen


def exhaustive_subset(G: np.ndarray, k: int, batch: int = 4096) -> tuple[list[int], float]:
    """Optimal k-subset (largest explained tr(G_SS^-1 (G^2)_SS)) and its residual^2."""
    n = G.shape[0]
    G = G / np.trace(G)  # scale: avoids overflow, same argmax
    H = G @ G
    d, h = np.diag(G), np.diag(H)
    if k == 1:
        gain = np.where(d > 0, h / np.where(d > 0, d, 1), -np.inf)
        p = int(np.argmax(gain))
        return [p], 1.0 - gain[p]
    best, best_set = -np.inf, None
    for m in range(k - 3, n - 2) if k > 2 else [-1]:
        # prefixes T (k-2 markers) with max(T) == m; pairs drawn from m+1..n-1
        prefixes = [(*t, m) for t in itertools.combinations(range(m), k - 3)] if k > 2 else [()]
        sub = np.arange(m + 1, n)
        iu, ju = np.triu_indices(sub.size, 1)  # the pairs p < q of sub
        for b0 in range(0, len(prefixes), batch):
            P = np.array(prefixes[b0 : b0 + batch], dtype=np.intp)
            if k == 2:
                P = np.zeros((1, 0), dtype=np.intp)
            if k > 2:
                GTT = G[P[:, :, None], P[:, None, :]]
                try:
                    L = np.linalg.cholesky(GTT)
                except np.linalg.LinAlgError:
                    L = _safe_cholesky(GTT)
                W = np.linalg.solve(L, G[P, :])  # (nb, k-2, n): L^-1 G_T:
                Gs = G[sub] - np.matmul(W[:, :, sub].transpose(0, 2, 1), W)  # G'[sub, :]
                explained_T = np.einsum("bti,bti->b", W, W)  # ||P_T A||_F^2 = ||L^-1 G_T:||_F^2
            else:
                Gs = np.broadcast_to(G[sub], (1, sub.size, n))
                explained_T = np.zeros(1)
            Hs = np.matmul(Gs, Gs.transpose(0, 2, 1))  # H'[sub, sub] = G'[sub,:] G'[:,sub]
            Gss = Gs[:, :, sub]
            dd = np.diagonal(Gss, axis1=1, axis2=2)
            hh = np.diagonal(Hs, axis1=1, axis2=2)
            # each pair (p, q), p < q, once: explained by {p, q} in the residual G'
            #   gain = (d_q h_p + d_p h_q - 2 G'_pq H'_pq) / (d_p d_q - G'_pq^2)
            dp, dq, hp, hq = dd[:, iu], dd[:, ju], hh[:, iu], hh[:, ju]
            gpq, hpq = Gss[:, iu, ju], Hs[:, iu, ju]
            dpq = dp * dq
            det = dpq - gpq * gpq
            num = dp * hq + dq * hp - 2.0 * gpq * hpq
            ok = det > 1e-10 * dpq
            with np.errstate(divide="ignore", invalid="ignore"):
                gain = np.where(ok, num / np.where(ok, det, 1.0), -np.inf)
            total = explained_T[:, None] + gain
            flat = int(np.argmax(total))
            if total.flat[flat] > best:
                best = float(total.flat[flat])
                bb, pair = np.unravel_index(flat, total.shape)
                best_set = [*P[bb].tolist(), int(sub[iu[pair]]), int(sub[ju[pair]])]
    return sorted(best_set), 1.0 - best


def _safe_cholesky(GTT):
    """Batched Cholesky that tolerates singular prefixes (their rows get a huge diagonal)."""
    out = np.empty_like(GTT)
    for b in range(GTT.shape[0]):
        try:
            out[b] = np.linalg.cholesky(GTT[b])
        except np.linalg.LinAlgError:
            out[b] = np.eye(GTT.shape[1]) * 1e150  # excludes the prefix: gain ~ 0
    return out


def subset_optimality(
    A, labels: Sequence[str] | None = None, k_max: int = 5, max_subsets: int = 10_000_000
) -> pd.DataFrame:
    """QR subset vs exhaustive optimum vs greedy forward selection, k = 1..k_max.

    Subsets are comma-separated labels (QR and greedy in selection order, optimal sorted by
    column).  qr_over_optimal = qr_residual_rms_mm / optimal_residual_rms_mm (>= 1).
    """
    A, labels = as_matrix(A, labels)
    ranking = rank_markers(A, labels)  # validates A
    rows, n = A.shape
    if isinstance(k_max, bool) or not isinstance(k_max, int | np.integer) or not 1 <= k_max < n:
        raise InputError(f"k_max: must be an integer in 1..{n - 1} (n markers), got {k_max!r}")
    G = A.T @ A
    residuals: dict[frozenset, float] = {}  # greedy and optimal subsets often coincide

    def residual(subset):
        key = frozenset(subset)
        if key not in residuals:
            residuals[key] = projection_residual(A, subset)
        return residuals[key]

    out = []
    for k in range(1, int(k_max) + 1):
        scale = np.sqrt(rows * (n - k))
        qr_set = [int(j) for j in ranking.order[:k]]
        qr_res = float(np.linalg.norm(ranking.R[k:, k:]))  # ||R22||_F
        gr_set = greedy_subset(G, k)
        gr_res = residual(gr_set)
        if math.comb(n, k) <= max_subsets:
            opt_set, _ = exhaustive_subset(G, k)
            opt_res = residual(opt_set)
            opt_lab = ",".join(labels[j] for j in opt_set)
        else:
            warnings.warn(
                f"subset_optimality: C({n},{k}) = {math.comb(n, k)} subsets exceeds "
                f"max_subsets={max_subsets}; exhaustive search not computed",
                stacklevel=2,
            )
            opt_res, opt_lab = float("nan"), NOT_COMPUTED
        out.append(
            {
                "k": k,
                "qr_subset": ",".join(labels[j] for j in qr_set),
                "qr_residual_rms_mm": qr_res / scale,
                "optimal_subset": opt_lab,
                "optimal_residual_rms_mm": opt_res / scale,
                "greedy_subset": ",".join(labels[j] for j in gr_set),
                "greedy_residual_rms_mm": gr_res / scale,
                "qr_over_optimal": qr_res / opt_res if opt_res > 0 else float("nan"),
            }
        )
    return pd.DataFrame(out, columns=COLUMNS)
