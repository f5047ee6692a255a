"""Marker selection with forced-in and excluded markers, scikit-learn style.

``MarkerSelector(k, force=..., exclude=...).fit(A).predict(P1)``: choose k main markers of the
displacement matrix A by QR with column pivoting (Lucero & Munhall 2008, Sec. III), then predict
every marker from the main markers' displacements P1 by A_s ~= A_m X, X = R11^-1 R12 (Sec. III,
eqs. 3-4).

Forced and excluded markers (as in PySensors' constrained sensor placement) are a small extension
of the pivoting: the candidates for each pivot are restricted to a group, and the groups are
exhausted in turn,

    1. the forced markers (pivoted among themselves),
    2. the free markers,
    3. the excluded markers (never main markers while k <= forced + free; they are ordered last
       so that R, and hence X = R11^-1 R12, still predicts them).

Within a group the rule is the usual one: the next pivot is the candidate whose column has the
largest component orthogonal to all pivots chosen so far.  We apply it to the n x n factor R0
of an unconstrained ranking (A^T A = R0^T R0, so every norm and inner product of A's columns is
R0's): for each group, project its columns orthogonally to the pivots so far and run pivoted QR
(LAPACK dgeqp3) on the projections; the final R is the unpivoted QR of R0 in the chosen order.
With no forced and no excluded marker this is exactly :func:`facemotion.rank_markers`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import scipy.linalg

from facemotion.errors import InputError
from facemotion.ranking.result import MarkerRanking, make_ranking
from facemotion.ranking.routes import rank_markers
from facemotion.regions.prediction import fit_coefficients


def _labels_in(name: str, wanted: Sequence[str], labels: Sequence[str]) -> list[str]:
    wanted = [str(x) for x in wanted]
    unknown = [m for m in wanted if m not in labels]
    if unknown:
        raise InputError(f"{name}: marker(s) {', '.join(unknown)} not among the "
                         f"{len(labels)} markers of A")
    if len(set(wanted)) != len(wanted):
        raise InputError(f"{name}: a marker is listed twice in {', '.join(wanted)}")
    return wanted


def constrained_ranking(A, labels: Sequence[str] | None = None, *, force: Sequence[str] = (),
                        exclude: Sequence[str] = (), method: str = "auto") -> MarkerRanking:
    """QR with column pivoting restricted to groups: forced markers first, then the free ones,
    excluded markers last (see the module docstring).  ``method``: the route of the
    unconstrained ranking that supplies R0 (:func:`facemotion.rank_markers`)."""
    base = rank_markers(A, labels, method=method)  # all input checks; a factor of A^T A
    labels = base.labels
    force = _labels_in("force", force, labels)
    exclude = _labels_in("exclude", exclude, labels)
    both = [m for m in force if m in exclude]
    if both:
        raise InputError(f"force/exclude: marker(s) {', '.join(both)} both forced and excluded")
    if not force and not exclude:
        return base
    if base.n_ranked < base.n:
        raise InputError(f"force/exclude: A ranks only {base.n_ranked} of its {base.n} markers "
                         "(fewer rows than markers); constraints need every marker ranked")
    n = base.n
    R0 = np.empty_like(base.R)
    R0[:, base.order] = base.R  # A^T A = R0^T R0, columns in the original order
    pos = {m: j for j, m in enumerate(labels)}
    free = [j for j in range(n) if labels[j] not in set(force) | set(exclude)]
    groups = [[pos[m] for m in force], free, [pos[m] for m in exclude]]
    order: list[int] = []
    tol = base.rtol * (base.r[0] if base.r.size else 0.0)
    for group in groups:
        if not group:
            continue
        C = R0[:, group]
        if order:
            # orthonormal basis of the pivots so far (their numerically independent part)
            Q, Rp = scipy.linalg.qr(R0[:, order], mode="economic")
            Q = Q[:, np.abs(np.diag(Rp)) > tol]
            for _ in range(2):  # project twice: orthogonal to working accuracy
                C = C - Q @ (Q.T @ C)
        _, piv = scipy.linalg.qr(C, mode="r", pivoting=True)
        order += [group[i] for i in piv]
    R = scipy.linalg.qr(R0[:, order], mode="r")[0]
    return make_ranking(R[:n], order, base.rows, labels, f"{base.method}+constrained", base.rtol)


class MarkerSelector:
    """Choose k main markers and predict all markers from them.

    Parameters
    ----------
    k : number of main markers (1 <= k < number of markers).
    force : markers that must be among the main markers (at most k).
    exclude : markers that must not be main markers (they are still predicted).
    method : QR route, as in :func:`facemotion.rank_markers`.

    Attributes after ``fit``: ``ranking_`` (:class:`~facemotion.ranking.result.MarkerRanking`),
    ``selected_`` (the k main marker labels, pivot order), ``coef_`` (X = R11^-1 R12 as a
    DataFrame, main x secondary markers), ``labels_`` (all markers, A's column order).
    """

    def __init__(self, k: int, *, force: Sequence[str] = (), exclude: Sequence[str] = (),
                 method: str = "auto"):
        self.k = k
        self.force = [str(x) for x in force]
        self.exclude = [str(x) for x in exclude]
        self.method = method

    def fit(self, A, labels: Sequence[str] | None = None) -> MarkerSelector:
        """Rank the markers of A (3F x n, mm; or a Displacements) under the constraints."""
        ranking = constrained_ranking(A, labels, force=self.force, exclude=self.exclude,
                                      method=self.method)
        k = self.k
        if len(self.force) > k:
            raise InputError(f"force: {len(self.force)} forced markers do not fit in k = {k}")
        if k > ranking.n - len(self.exclude):
            raise InputError(f"k: {k} main markers but only {ranking.n - len(self.exclude)} "
                             "markers are not excluded")
        self.coef_ = fit_coefficients(ranking, k)  # X = R11^-1 R12; checks 1 <= k < n, rank
        self.ranking_ = ranking
        self.selected_ = list(ranking.labels_in_order[:k])
        self.labels_ = list(ranking.labels)
        return self

    def predict(self, P1, labels: Sequence[str] | None = None) -> pd.DataFrame:
        """All markers' displacements (3F x n DataFrame, A's column order) from the main ones.

        P1: the main markers' displacements (3F x k, mm): a DataFrame whose columns include
        ``selected_``, or an array with columns ``labels`` (default: ``selected_`` in order).
        Main-marker columns are copied; the others are P1 X (A_s ~= A_m X).  A DataFrame's
        index is kept.
        """
        if not hasattr(self, "coef_"):
            raise InputError("MarkerSelector: call fit(A) before predict")
        index = None
        if isinstance(P1, pd.DataFrame):
            labels, index = [str(c) for c in P1.columns], P1.index
            P1 = P1.to_numpy(dtype=float)
        P1 = np.asarray(P1, dtype=float)
        labels = self.selected_ if labels is None else [str(x) for x in labels]
        if P1.ndim != 2 or P1.shape[1] != len(labels) or P1.shape[0] % 3:
            raise InputError(f"P1: expected a (3F x {len(labels)}) matrix, got {P1.shape}")
        missing = [m for m in self.selected_ if m not in labels]
        if missing:
            raise InputError(f"P1: lacks main marker(s) {', '.join(missing)}")
        Am = P1[:, [labels.index(m) for m in self.selected_]]
        if not np.isfinite(Am).all():
            raise InputError("P1: NaN or inf displacements in the main markers")
        pred = pd.DataFrame(Am, columns=self.selected_, index=index)
        secondary = pd.DataFrame(Am @ self.coef_.to_numpy(), columns=list(self.coef_.columns),
                                 index=index)
        return pd.concat([pred, secondary], axis=1)[self.labels_]
