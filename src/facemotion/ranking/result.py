"""The result of a ranking: pivot order, R, and the checks every route shares.

``MarkerRanking`` holds A P = Q R's pivot order and R (rows signed so that diag(R) >= 0);
``make_ranking`` builds it from any route's R. The readings of "R values normalized to the size
of R" (Lucero & Munhall 2008, Fig. 2) are ``R_NORMALISATIONS`` (see :mod:`facemotion.ranking`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError

#: A marker whose largest absolute displacement is below this (mm) is static.
STATIC_MM = 1e-12


#: Machine epsilon of float64.
EPS = np.finfo(float).eps


log = logging.getLogger("facemotion")


#: Readings of "R values normalized to the size of R" (Fig. 2); see the module notes.
R_NORMALISATIONS = ("none", "per_coordinate", "per_frame")


DEFAULT_R_NORMALISATION = "none"
#: ``tolerance_from`` of an epsilon-rank at a tolerance the caller asked for (the setting).
ASKED = "qr.tolerances_mm"


def r_scale(rows: int, normalisation: str = DEFAULT_R_NORMALISATION) -> float:
    """The divisor applied to R (and R22) under a normalisation, for A with ``rows`` = 3M."""
    if normalisation == "none":
        return 1.0
    if normalisation == "per_coordinate":
        return float(np.sqrt(rows))             # RMS per coordinate sample
    if normalisation == "per_frame":
        return float(np.sqrt(rows / 3.0))       # RMS 3-D size per frame
    raise InputError(f"normalisation: unknown R normalisation {normalisation!r}; use one of "
                     f"{', '.join(R_NORMALISATIONS)}")


def implied_rms_per_coordinate(r_value: float, rows: int,
                               normalisation: str = DEFAULT_R_NORMALISATION) -> float:
    """The RMS per coordinate sample (mm) of a pivot's orthogonal component that an R value
    quoted under ``normalisation`` implies for A with ``rows`` = 3M rows: r * scale / sqrt(3M).

    E.g. the paper's r56 = 22.70 mm with 3M = 27,000: 0.14 mm under "none", 22.70 mm under
    "per_coordinate", 13.1 mm under "per_frame" (docs/methods.md).
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


def is_row_blocks(A) -> bool:
    """A on disk, read in blocks (:class:`facemotion.ingest.displacement_file.RowBlocks`)."""
    return hasattr(A, "blocks") and hasattr(A, "shape") and not isinstance(A, np.ndarray)


def as_matrix(A, labels):
    """Accept a plain array + labels, or a Displacements-like object with .A and .labels,
    or a RowBlocks (kept on disk)."""
    if is_row_blocks(A):
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
    if is_row_blocks(A):
        bad = np.zeros(A.shape[1], dtype=bool)
        for blk in A.blocks():
            bad |= ~np.isfinite(blk).all(axis=0)
    else:
        bad = ~np.isfinite(A).all(axis=0)
    return [labels[j] for j in np.flatnonzero(bad)]


def raise_nonfinite(A, labels, name="A"):
    bad = nonfinite_markers(A, labels)
    raise InputError(f"{name}: NaN or inf displacements in marker(s) {', '.join(bad)}")


def check_column_norms(A, labels, sq_norms, name="A"):
    """NaN/inf and static markers, from the squared column norms of a pass already made.

    max|a_j| <= ||a_j|| <= sqrt(rows) max|a_j|, so a column is certainly moving when
    ||a_j|| >= sqrt(rows) * STATIC_MM; only the few below are looked at directly.
    """
    if not np.all(np.isfinite(sq_norms)):
        raise_nonfinite(A, labels, name)
    suspects = np.flatnonzero(np.sqrt(sq_norms) < np.sqrt(A.shape[0]) * STATIC_MM)
    if suspects.size:
        cols = A.columns(suspects) if is_row_blocks(A) else A[:, suspects]
        peak = np.max(np.abs(cols), axis=0)
    static = [labels[j] for j, p in zip(suspects, peak if suspects.size else [], strict=True)
              if p < STATIC_MM]
    if static:
        raise InputError(
            f"{name}: marker(s) {', '.join(static)} never move (max |displacement| < "
            f"{STATIC_MM:g} mm): a static marker has no motion to rank; drop it"
        )


def complete_order(piv: np.ndarray, n: int) -> np.ndarray:
    rest = np.setdiff1d(np.arange(n), piv, assume_unique=False)
    return np.concatenate([piv, rest]).astype(np.intp)


def make_ranking(R, order, A_rows, labels, method, rtol, n_ranked=None, tail="zero"):
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


def rest_in_original_order(order: np.ndarray, m: int, n: int | None = None) -> np.ndarray:
    """The first m pivots, then the other of the n columns in their original order."""
    head = np.asarray(order[:m], dtype=np.intp)
    n = len(order) if n is None else n
    return np.concatenate([head, np.setdiff1d(np.arange(n), head)]).astype(np.intp)


def n_ranked_for(rows: int, n: int, k_max: int | None) -> int:
    return min(rows, n, n if k_max is None else int(k_max))


def selection_table(orders: Mapping[str, MarkerRanking | Sequence[str]],
                    n: int = 10) -> pd.DataFrame:
    """Table I of Lucero & Munhall (2008): the first ``n`` markers in pivot order, one column
    per dataset (subject).  ``orders``: dataset label -> a ranking or its labels in pivot order;
    a dataset with fewer than n markers gets empty cells."""
    table = pd.DataFrame({"order": np.arange(1, n + 1)})
    for label, order in orders.items():
        markers = list(getattr(order, "labels_in_order", order))[:n]
        table[str(label)] = [str(m) for m in markers] + [""] * (n - len(markers))
    return table
