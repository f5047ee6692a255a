"""Predicting all markers from k main markers (Lucero & Munhall 2008, Sec. III, eqs. 2-4; Sec. V).

With A P = Q R partitioned after the first k pivots,

    R = [[R11, R12], [0, R22]],      A_s ~= A_m X,   X = R11^-1 R12            (eqs. 1, 4)

where A_m holds the k main (pivot) markers and A_s the n - k secondary ones.  X is the least
squares solution on the training data and its residual is ||A_s - A_m X||_F = ||R22||_F.

Held-out error for every k from one factorization (``error_curve``): with B_P the held-out
matrix in pivot order, C = B_P R^-1 expresses B in the training's orthogonal coordinates
(column i of C is the held-out motion along the training's i-th orthogonal direction).  Since
R is upper triangular, the first k columns of C only need R11: C[:, :k] = B_P[:, :k] R11^-1.
The prediction of secondary column j >= k is B_m X[:, j] = C[:, :k] R[:k, j], so the residuals

    E^(k)[:, j] = B_P[:, j] - sum_{i<k} C[:, i] R[i, j]          (j >= k)

change by one rank-one term from k to k + 1: E^(k+1) = E^(k) - C[:, k] R[k, :].  All n - 1
curves cost O(rows n^2) in total, like one more QR, instead of one least-squares fit per k.

Error measures (held-out frames x secondary markers; the k main markers are exact).  The
paper's Fig. 10 plots a mean absolute error (top) and a mean relative error (bottom), "high
... because of the small displacements of most markers": a relative error averaged over
markers, in which each marker's error is divided by its own motion.

* ``mean_abs_error_mm`` (Fig. 10 top): mean 3-D Euclidean distance between measured and
  predicted position.
* ``rel_error_per_marker`` (Fig. 10 bottom): for each secondary marker, its mean 3-D error
  divided by its mean 3-D displacement magnitude; the mean of these ratios over the markers.
* ``median_abs_error_mm``, ``max_abs_error_mm``: median and maximum of the same distances.
* ``rms_error_mm``: RMS over all secondary-marker coordinates (x, y, z separately), i.e.
  ||E||_F / sqrt(3 F (n - k)) = sqrt(mean squared distance / 3).
* ``rel_error_pooled``: sum of 3-D error distances / sum of 3-D measured displacement
  magnitudes, both over the secondary markers and held-out frames (0 = perfect, 1 = as large as
  the motion); dominated by the markers that move most.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import scipy.linalg

from facemotion.errors import InputError
from facemotion.ranking.result import MarkerRanking, nonfinite_markers

CURVE_COLUMNS = [
    "k",
    "mean_abs_error_mm",
    "rms_error_mm",
    "median_abs_error_mm",
    "max_abs_error_mm",
    "rel_error_per_marker",
    "rel_error_pooled",
    "pivot_marker",
    "main_markers",
]


def _check_k(ranking: MarkerRanking, k) -> int:
    n = ranking.n
    rank = ranking.numerical_rank()
    if isinstance(k, bool) or not isinstance(k, int | np.integer):
        raise InputError(f"k: number of main markers must be an integer, got {k!r}")
    k = int(k)
    if not 1 <= k < n:
        raise InputError(f"k: {k} main markers is outside 1 <= k < n = {n} markers")
    if k > rank:
        raise InputError(
            f"k: {k} main markers exceeds the numerical rank {rank} of A "
            "(R11 would be singular: the later pivots are linear combinations of earlier ones)"
        )
    return k


def coefficients(ranking: MarkerRanking, k: int) -> np.ndarray:
    """X = R11^-1 R12 as an array (k x n-k), rows/columns in pivot order."""
    k = _check_k(ranking, k)
    R = ranking.R
    return scipy.linalg.solve_triangular(R[:k, :k], R[:k, k:], lower=False)  # X = R11^-1 R12


def fit_coefficients(ranking: MarkerRanking, k: int) -> pd.DataFrame:
    """X = R11^-1 R12: A_s ~= A_m X.  Index: main marker labels, columns: secondary labels."""
    X = coefficients(ranking, k)
    lab = ranking.labels_in_order
    return pd.DataFrame(X, index=pd.Index(lab[:k], name="main"), columns=lab[k:])


def residual_norm(ranking: MarkerRanking, k: int) -> float:
    """||R22||_F = ||A_s - A_m X||_F on the training data (mm * sqrt(rows))."""
    k = _check_k(ranking, k)
    return float(np.linalg.norm(ranking.R[k:, k:]))


def _align(ranking: MarkerRanking, B, labels, name="B") -> np.ndarray:
    """B with its columns in the training's pivot order (matched by label)."""
    B, cols = _pivot_columns(ranking, B, labels, name)
    return B[:, cols]


def _pivot_columns(ranking: MarkerRanking, B, labels, name="B") -> tuple[np.ndarray, list[int]]:
    """B as floats and the column of each of the training's markers in pivot order (matched by
    label), after checking B's shape, labels and values."""
    B = np.asarray(B, dtype=float)
    labels = [str(x) for x in labels]
    if B.ndim != 2 or B.shape[1] != len(labels) or B.shape[0] % 3 or B.shape[0] == 0:
        raise InputError(f"{name}: expected a (3F x {len(labels)}) matrix, got shape {B.shape}")
    pos = {lab: j for j, lab in enumerate(labels)}
    missing = [lab for lab in ranking.labels_in_order if lab not in pos]
    if missing:
        raise InputError(f"{name}: held-out data lacks training marker(s) {', '.join(missing)}")
    bad = nonfinite_markers(B, labels)
    if bad:
        raise InputError(f"{name}: NaN or inf displacements in marker(s) {', '.join(bad)}")
    return B, [pos[lab] for lab in ranking.labels_in_order]


def _stats(D2: np.ndarray, mag: np.ndarray, k: int, main: str) -> dict:
    """Error measures from D2 (n_sec, F): each secondary marker's squared 3-D residual distance
    in every held-out frame (marker-major, C-contiguous; overwritten); mag (n_sec,) = each
    secondary marker's sum over frames of its measured 3-D displacement magnitude."""
    sq_sum = float(D2.sum())
    dist = np.sqrt(D2, out=D2)  # 3-D distance per marker and frame
    count = dist.size
    per_marker = dist.sum(axis=1)
    total = float(per_marker.sum())
    dist_max = float(dist.max())
    mag = np.asarray(mag, dtype=float)
    mag_sum = float(mag.sum())
    with np.errstate(divide="ignore", invalid="ignore"):
        per_marker /= mag    # a marker that never moves: inf (or nan)
    return {
        "k": k,
        "mean_abs_error_mm": total / count,
        "rms_error_mm": float(np.sqrt(sq_sum / count / 3.0)),
        "median_abs_error_mm": _median_inplace(dist.reshape(-1)),
        "max_abs_error_mm": dist_max,
        "rel_error_per_marker": float(per_marker.mean()),
        "rel_error_pooled": total / mag_sum if mag_sum > 0 else float("nan"),
        "pivot_marker": main.rsplit(",", 1)[-1],  # the main marker added at this k
        "main_markers": main,
    }


def _median_inplace(x: np.ndarray) -> float:
    """np.median of a finite 1-D array (the mean of the two middle values when the length is
    even), partitioning ``x`` in place instead of a copy."""
    h = x.size // 2
    if x.size % 2:
        x.partition(h)
        return float(x[h])
    x.partition([h - 1, h])
    return float((x[h - 1] + x[h]) / 2.0)


def _sq_dist(E: np.ndarray) -> np.ndarray:
    """(n_sec, 3, F) residuals -> (n_sec, F) squared 3-D distances."""
    return np.einsum("jcf,jcf->jf", E, E)


def _zero_row(n: int, lab: list[str]) -> dict:
    return {
        "k": n,
        "mean_abs_error_mm": 0.0,
        "rms_error_mm": 0.0,
        "median_abs_error_mm": 0.0,
        "max_abs_error_mm": 0.0,
        "rel_error_per_marker": 0.0,
        "rel_error_pooled": 0.0,
        "pivot_marker": "",
        "main_markers": ",".join(lab),
    }


def _k_stop(rk: MarkerRanking, k_max) -> int:
    """Last k of a curve: the numerical rank (R11 must be invertible), n - 1, and k_max."""
    stop = min(rk.numerical_rank(), rk.n - 1)
    if k_max is not None:
        if isinstance(k_max, bool) or not isinstance(k_max, int | np.integer) or k_max < 1:
            raise InputError(f"k_max: must be a positive integer, got {k_max!r}")
        stop = min(stop, int(k_max))
    return stop


def residual_steps(train_ranking: MarkerRanking, B, labels: Sequence[str],
                   k_max: int | None = None):
    """Yield (k, E_s, mag) for k = 1..min(rank, k_max): E_s (n - k, 3, F) the held-out residuals
    of the secondary markers in pivot order (a view, overwritten by the next step) and mag
    (n - k,) each one's summed 3-D displacement magnitude.  The rank-one updates of the module
    notes: E^(k) = E^(k-1) - C[:, k-1] R[k-1, :], C[:, :k] = B_P[:, :k] R11^-1."""
    rk = train_ranking
    Bp = _align(rk, B, labels)
    F = Bp.shape[0] // 3
    n = rk.n
    rank = _k_stop(rk, k_max)
    R = rk.R
    # C[:, :rank] = B_P[:, :rank] R11^-1   (solve R11^T C^T = B_P^T)
    C = scipy.linalg.solve_triangular(R[:rank, :rank], Bp[:, :rank].T, trans="T").T
    # residuals E^(k) marker-major, E[j] = marker j's (3, frames): the secondary markers j >= k
    # are one contiguous block for each update and each k's measures
    E = np.ascontiguousarray(Bp.reshape(F, 3, n).transpose(2, 1, 0))
    Cm = np.ascontiguousarray(C.reshape(F, 3, rank).transpose(2, 1, 0))
    mag = np.sqrt(_sq_dist(E)).sum(axis=1)
    step = np.empty_like(E)
    for k in range(1, rank + 1):
        # E^(k) = E^(k-1) - C[:, k-1] R[k-1, :]   (rank-one update, secondary columns only)
        Es = E[k:]
        np.subtract(Es, np.multiply(R[k - 1, k:, None, None], Cm[k - 1], out=step[k:]),
                    out=Es)
        yield k, Es, mag[k:]


def error_curve(train_ranking: MarkerRanking, B, labels: Sequence[str],
                k_max: int | None = None) -> pd.DataFrame:
    """Held-out prediction error for every k = 1..min(rank, k_max) (and k = n, zero error).

    k stops at the numerical rank of the training data (R11 must be invertible) and at
    ``k_max`` (cost O(rows n k_max)); k = n is always reported (every marker main: zero
    error).  Columns: see the module docstring.
    """
    rk = train_ranking
    lab = rk.labels_in_order
    out = [_stats(_sq_dist(Es), mag, k, ",".join(lab[:k]))
           for k, Es, mag in residual_steps(rk, B, labels, k_max)]
    out.append(_zero_row(rk.n, lab))
    return pd.DataFrame(out, columns=CURVE_COLUMNS)


def error_curve_rms(train_ranking: MarkerRanking, B, labels: Sequence[str],
                    k_max: int | None = None) -> pd.DataFrame:
    """RMS-only held-out error for every k from Gram matrices of B (frame count drops out).

    With G = B_P^T B_P (one pass over B) and X = R11^-1 R12,

        ||B_s - B_m X||_F^2 = tr(X^T G_mm X) - 2 tr(X^T G_ms) + tr(G_ss)

    O(n^3) per k, independent of the number of held-out frames.  It subtracts large numbers, so
    its absolute error is about eps * ||B_s||_F^2: negligible unless the error is ~1e-7 of the
    motion.  k stops at min(rank, k_max).  Columns: k, rms_error_mm, main_markers.
    """
    rk = train_ranking
    Bp = _align(rk, B, labels)
    rows = Bp.shape[0]
    n = rk.n
    lab = rk.labels_in_order
    rank = _k_stop(rk, k_max)
    G = Bp.T @ Bp
    R = rk.R
    out = []
    for k in range(1, rank + 1):
        X = scipy.linalg.solve_triangular(R[:k, :k], R[:k, k:])  # X = R11^-1 R12
        Gmm, Gms = G[:k, :k], G[:k, k:]
        sq = np.sum(X * (Gmm @ X)) - 2.0 * np.sum(X * Gms) + np.trace(G[k:, k:])
        rms = np.sqrt(max(sq, 0.0) / (rows * (n - k)))
        out.append({"k": k, "rms_error_mm": float(rms), "main_markers": ",".join(lab[:k])})
    out.append({"k": n, "rms_error_mm": 0.0, "main_markers": ",".join(lab)})
    return pd.DataFrame(out, columns=["k", "rms_error_mm", "main_markers"])


def error_curve_naive(
    A, B, labels: Sequence[str], ranking: MarkerRanking, measures: str = "all"
) -> pd.DataFrame:
    """Reference: for each k, least squares X = lstsq(A_m, A_s) on the training data A, then
    the error of B_m X on the held-out B.  ``measures="rms"`` computes only rms_error_mm."""
    A = np.asarray(A, dtype=float)
    Ap = _align(ranking, A, labels, name="A")
    Bp = _align(ranking, B, labels)
    F = Bp.shape[0] // 3
    n = ranking.n
    lab = ranking.labels_in_order
    rank = min(ranking.numerical_rank(), n - 1)
    out = []
    for k in range(1, rank + 1):
        X = np.linalg.lstsq(Ap[:, :k], Ap[:, k:], rcond=None)[0]
        E = Bp[:, k:] - Bp[:, :k] @ X
        if measures == "rms":
            rms = float(np.sqrt(np.mean(E * E)))
            out.append({"k": k, "rms_error_mm": rms, "main_markers": ",".join(lab[:k])})
            continue
        Bs = Bp[:, k:].reshape(F, 3, n - k)
        mag = np.sqrt((Bs**2).sum(axis=1)).sum(axis=0)
        D2 = np.ascontiguousarray((E.reshape(F, 3, n - k) ** 2).sum(axis=1).T)
        out.append(_stats(D2, mag, k, ",".join(lab[:k])))
    if measures == "rms":
        out.append({"k": n, "rms_error_mm": 0.0, "main_markers": ",".join(lab)})
        return pd.DataFrame(out, columns=["k", "rms_error_mm", "main_markers"])
    out.append(_zero_row(n, lab))
    return pd.DataFrame(out, columns=CURVE_COLUMNS)


def predict(ranking: MarkerRanking, k: int, B, labels: Sequence[str] | None = None) -> np.ndarray:
    """Predicted displacements of all markers from the k main markers of B.

    B: (3F x n) with columns in ``labels`` order (default: the ranking's original label order).
    Returns an array shaped like B, same column order; main-marker columns are copied exactly,
    secondary columns are B_m X.
    """
    labels = ranking.labels if labels is None else [str(x) for x in labels]
    B = np.asarray(B, dtype=float)
    Bp = _align(ranking, B, labels)
    X = coefficients(ranking, k)
    pred_p = np.empty_like(Bp)
    pred_p[:, :k] = Bp[:, :k]
    pred_p[:, k:] = Bp[:, :k] @ X  # A_s ~= A_m X
    pos = {lab: j for j, lab in enumerate(labels)}
    out = B.copy()
    out[:, [pos[lab] for lab in ranking.labels_in_order]] = pred_p
    return out


def trajectory_errors(
    B_true,
    B_pred,
    labels: Sequence[str],
    marker: str,
    row_frame: np.ndarray | None = None,
) -> pd.DataFrame:
    """Largest absolute error per axis (x, y, z) of one marker's predicted trajectory.

    Columns: marker, axis, max_abs_error_mm, frame (frame index of the maximum; from
    ``row_frame`` when given, else the frame number within B), rms_error_mm.
    """
    labels = [str(x) for x in labels]
    B_true = np.asarray(B_true, dtype=float)
    B_pred = np.asarray(B_pred, dtype=float)
    if B_true.shape != B_pred.shape:
        raise InputError(f"B_pred: shape {B_pred.shape} differs from B_true {B_true.shape}")
    if str(marker) not in labels:
        raise InputError(f"marker: {marker!r} is not one of the markers")
    j = labels.index(str(marker))
    F = B_true.shape[0] // 3
    err = (B_pred[:, j] - B_true[:, j]).reshape(F, 3)
    frames = np.arange(F) if row_frame is None else np.asarray(row_frame)[::3]
    out = []
    for c, axis in enumerate("xyz"):
        f = int(np.argmax(np.abs(err[:, c])))
        out.append(
            {
                "marker": str(marker),
                "axis": axis,
                "max_abs_error_mm": float(abs(err[f, c])),
                "frame": int(frames[f]),
                "rms_error_mm": float(np.sqrt(np.mean(err[:, c] ** 2))),
            }
        )
    return pd.DataFrame(out)
