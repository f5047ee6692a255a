"""Marker selection with forced-in and excluded markers, as a scikit-learn estimator.

``MarkerSelector(k=..., force=..., exclude=...).fit(X)``: choose k main markers by QR with column
pivoting (Lucero & Munhall 2008, Sec. III) of the displacement matrix A built from X, then
``transform`` keeps the main markers' columns and ``predict`` reconstructs every marker from
them by A_s ~= A_m X, X = R11^-1 R12 (Sec. III, eqs. 3-4).  X is frames x (marker, axis) columns, as
``Recording.to_frame`` gives: an array (F, 3n), or a DataFrame whose columns are a
(marker, axis) MultiIndex (the labels are taken from it).  Its rows become A's rows
(frame, axis), frame-major; with ``center`` (default) the columns' training means are
subtracted first (a neutral pose; set center=False to pass displacements from your own
neutral, the paper's A).

scikit-learn is optional: with it installed the class is a ``BaseEstimator`` and
``TransformerMixin`` (``clone``, ``Pipeline``, ``GridSearchCV``); without it, ``get_params`` and
``set_params`` are provided here.  ``score`` is minus the mean 3-D prediction error (mm) of
the secondary markers, so that larger is better.

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

import inspect
import warnings
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


try:  # scikit-learn is optional (the 'sklearn' extra)
    from sklearn.base import BaseEstimator as _Base
    from sklearn.base import TransformerMixin as _Transformer
except ImportError:  # pragma: no cover - exercised where scikit-learn is absent
    class _Base:
        """get_params / set_params as scikit-learn's BaseEstimator defines them."""

        @classmethod
        def _get_param_names(cls) -> list[str]:
            sig = inspect.signature(cls.__init__)
            return sorted(p for p in sig.parameters if p != "self")

        def get_params(self, deep: bool = True) -> dict:
            return {name: getattr(self, name) for name in self._get_param_names()}

        def set_params(self, **params):
            for name, value in params.items():
                if name not in self._get_param_names():
                    raise ValueError(f"invalid parameter {name!r} for {type(self).__name__}")
                setattr(self, name, value)
            return self

    class _Transformer:
        def fit_transform(self, X, y=None, **fit_params):
            return self.fit(X, y, **fit_params).transform(X)

try:
    from sklearn.exceptions import NotFittedError as _NotFitted
except ImportError:  # pragma: no cover
    _NotFitted = AttributeError


class NotFittedError(InputError, _NotFitted):
    """A MarkerSelector used before ``fit``: a facemotion error and scikit-learn's
    NotFittedError (when scikit-learn is installed)."""

AXES = ("x", "y", "z")


def _as_frames(X, labels=None) -> tuple[np.ndarray, list[str] | None, object]:
    """X (F, 3n) as an array, the marker labels of a (marker, axis) DataFrame (else None), and
    the DataFrame's index (else None)."""
    if isinstance(X, pd.DataFrame):
        cols = X.columns
        if isinstance(cols, pd.MultiIndex) and cols.nlevels == 2:
            markers = [str(m) for m in cols.get_level_values(0)]
            axes = [str(a) for a in cols.get_level_values(1)]
            labels = markers[::3]
            if len(markers) % 3 or axes != list(AXES) * (len(markers) // 3) \
                    or markers != [m for m in labels for _ in AXES]:
                raise InputError("X: DataFrame columns must be (marker, axis) pairs with axes "
                                 "x, y, z of each marker in turn, as Recording.to_frame gives")
            return X.to_numpy(dtype=float), labels, X.index
        return X.to_numpy(dtype=float), None, X.index
    if hasattr(X, "toarray") or type(X).__module__.startswith("scipy.sparse"):
        raise TypeError("X: sparse input is not supported; pass a dense array (frames x "
                        "(marker, axis))")
    arr = np.asarray(X)
    if np.iscomplexobj(arr):
        raise ValueError("X: Complex data not supported (marker coordinates are real, mm)")
    return arr.astype(float, copy=False), None, None


def _frames_to_A(Xf: np.ndarray) -> np.ndarray:
    """(F, 3n) frames x (marker, axis) -> A (3F, n), rows (frame, axis) frame-major."""
    F, c = Xf.shape
    return Xf.reshape(F, c // 3, 3).transpose(0, 2, 1).reshape(3 * F, c // 3)


def _A_to_frames(A: np.ndarray) -> np.ndarray:
    rows, n = A.shape
    return A.reshape(rows // 3, 3, n).transpose(0, 2, 1).reshape(rows // 3, 3 * n)


class MarkerSelector(_Transformer, _Base):
    """Choose k main markers; ``transform`` keeps them, ``predict`` reconstructs all markers.

    Parameters
    ----------
    k : number of main markers (1 <= k < number of markers).
    force : markers that must be among the main markers (at most k).
    exclude : markers that must not be main markers (they are still predicted).
    method : QR route, as in :func:`facemotion.rank_markers`.
    center : subtract each column's training mean before ranking (module notes).
    labels : marker labels for an array X (default: a DataFrame's, else m0, m1, ...).

    Attributes after ``fit``: ``ranking_`` (:class:`~facemotion.ranking.result.MarkerRanking`),
    ``selected_`` (the k main marker labels, pivot order), ``coef_`` (X = R11^-1 R12 as a
    DataFrame, main x secondary markers), ``labels_`` (all markers, X's column order),
    ``mean_`` ((n, 3) training mean per marker and axis, zeros without ``center``),
    ``n_features_in_`` (3n).
    """

    def __init__(self, k: int = 10, *, force: Sequence[str] = (), exclude: Sequence[str] = (),
                 method: str = "auto", center: bool = True, labels: Sequence[str] | None = None):
        self.k = k
        self.force = force
        self.exclude = exclude
        self.method = method
        self.center = center
        self.labels = labels

    def fit(self, X, y=None) -> MarkerSelector:
        """Rank the markers of X (frames x (marker, axis), mm) under the constraints.  ``y`` is
        ignored.  (The 0.2 form ``fit(A, labels)`` with A (3F x n) or a ``Displacements`` works
        until 0.3, with a DeprecationWarning.)"""
        if hasattr(X, "A") and hasattr(X, "labels") or _is_label_list(y):
            warnings.warn("MarkerSelector.fit(A, labels) with A (3F x n) is deprecated; pass X "
                          "as frames x (marker, axis) columns (Recording.to_frame)",
                          DeprecationWarning, stacklevel=2)
            A, labels = (X.A, X.labels) if hasattr(X, "A") else (np.asarray(X, float), y)
            return self._fit_A(np.asarray(A, dtype=float), [str(m) for m in labels], None)
        Xf, labels, _ = _as_frames(X)
        self._check_frames(Xf, "X")
        n = Xf.shape[1] // 3
        labels = labels or ([str(m) for m in self.labels] if self.labels is not None
                            else [f"m{j}" for j in range(n)])
        if len(labels) != n:
            raise InputError(f"labels: {len(labels)} labels for {n} markers of X")
        mean = Xf.mean(axis=0) if self.center else np.zeros(Xf.shape[1])
        return self._fit_A(_frames_to_A(Xf - mean), labels, mean.reshape(n, 3))

    @staticmethod
    def _check_frames(Xf: np.ndarray, name: str) -> None:
        if Xf.ndim != 2:
            raise ValueError(f"{name}: expected a 2-D array (frames x (marker, axis)), got "
                             f"{Xf.ndim}-D")
        if Xf.shape[0] < 1:
            raise ValueError(f"{name}: 0 sample(s) (frames); at least one is required")
        if Xf.shape[1] == 0:
            raise ValueError(f"{name}: 0 feature(s) (shape={Xf.shape}) while a minimum of 3 "
                             "is required.")
        if Xf.shape[1] % 3:
            raise ValueError(f"{name}: n_features = {Xf.shape[1]} column(s); expected 3 per "
                             "marker (x, y, z)")
        if not np.isfinite(Xf).all():
            raise ValueError(f"{name}: Input contains NaN or infinity; fill gaps first")

    def _fit_A(self, A: np.ndarray, labels: list[str], mean) -> MarkerSelector:
        force = [str(x) for x in self.force]
        exclude = [str(x) for x in self.exclude]
        ranking = constrained_ranking(A, labels, force=force, exclude=exclude,
                                      method=self.method)
        k = self.k
        if len(force) > k:
            raise InputError(f"force: {len(force)} forced markers do not fit in k = {k}")
        if k > ranking.n - len(exclude):
            raise InputError(f"k: {k} main markers but only {ranking.n - len(exclude)} "
                             "markers are not excluded")
        self.coef_ = fit_coefficients(ranking, k)  # X = R11^-1 R12; checks 1 <= k < n, rank
        self.ranking_ = ranking
        self.selected_ = list(ranking.labels_in_order[:k])
        self.labels_ = list(ranking.labels)
        self.mean_ = np.zeros((len(labels), 3)) if mean is None else mean
        self.n_features_in_ = 3 * len(labels)
        return self

    def _check_fitted(self, what: str) -> None:
        if not hasattr(self, "coef_"):
            raise NotFittedError(f"MarkerSelector: call fit(X) before {what}")

    def _main_frames(self, X) -> tuple[np.ndarray, object]:
        """The main markers' (F, 3k) columns of X: X with all markers (as in fit), or a
        DataFrame holding at least the main markers."""
        Xf, labels, index = _as_frames(X)
        self._check_frames(Xf, "X")
        labels = labels or (self.labels_ if Xf.shape[1] == self.n_features_in_ else None)
        if labels is None:
            raise ValueError(f"X: {Xf.shape[1]} columns; expected {self.n_features_in_} "
                             "(every marker, as in fit) or a (marker, axis) DataFrame")
        missing = [m for m in self.selected_ if m not in labels]
        if missing:
            raise InputError(f"X: lacks main marker(s) {', '.join(missing)}")
        cols = [3 * labels.index(m) + c for m in self.selected_ for c in range(3)]
        return Xf[:, cols], index

    def transform(self, X):
        """The main markers' columns of X (frames x (marker, axis)), in pivot order."""
        self._check_fitted("transform")
        Xm, index = self._main_frames(X)
        if isinstance(X, pd.DataFrame):
            cols = pd.MultiIndex.from_product([self.selected_, list(AXES)],
                                              names=["marker", "axis"])
            return pd.DataFrame(Xm, index=index, columns=cols)
        return Xm

    def predict(self, X, labels: Sequence[str] | None = None):
        """Every marker reconstructed from the main markers' columns of X: A_s = A_m X
        (Sec. II.D) per frame and axis, plus the training means.  An array in, an array
        (F, 3n) out, markers in ``labels_`` order; a (marker, axis) DataFrame in, one out (its
        index kept).  Main-marker columns are copied.  (The 0.2 form ``predict(P1)`` with P1
        (3F x k) rows (frame, axis) works until 0.3, with a DeprecationWarning.)"""
        self._check_fitted("predict")
        if _old_predict_form(X, labels, len(self.selected_)):
            warnings.warn("MarkerSelector.predict(P1) with P1 (3F x k) is deprecated; pass X "
                          "as frames x (marker, axis) columns", DeprecationWarning, stacklevel=2)
            return self._predict_A(X, labels)
        Xm, index = self._main_frames(X)
        F, k = Xm.shape[0], len(self.selected_)
        pos = {m: j for j, m in enumerate(self.labels_)}
        main_mean = self.mean_[[pos[m] for m in self.selected_]]       # (k, 3)
        Am = _frames_to_A(Xm - main_mean.reshape(1, 3 * k))             # (3F, k)
        As = Am @ self.coef_.to_numpy()                                  # (3F, n - k)
        full = np.empty((3 * F, len(self.labels_)))
        full[:, [pos[m] for m in self.selected_]] = Am
        full[:, [pos[m] for m in self.coef_.columns]] = As
        out = _A_to_frames(full) + self.mean_.reshape(1, -1)
        out[:, [3 * pos[m] + c for m in self.selected_ for c in range(3)]] = Xm
        if isinstance(X, pd.DataFrame):
            cols = pd.MultiIndex.from_product([self.labels_, list(AXES)],
                                              names=["marker", "axis"])
            return pd.DataFrame(out, index=index, columns=cols)
        return out

    def score(self, X, y=None) -> float:
        """Minus the mean 3-D distance (mm) between the secondary markers of X and their
        prediction from the main ones (larger is better, as scikit-learn's search expects)."""
        self._check_fitted("score")
        Xf, labels, _ = _as_frames(X)
        self._check_frames(Xf, "X")
        labels = labels or self.labels_
        if sorted(labels) != sorted(self.labels_):
            raise InputError("X: score needs every marker of fit (its measured secondary "
                             "markers are the reference)")
        pred = np.asarray(self.predict(np.asarray(Xf)[:, _reorder(labels, self.labels_)]))
        truth = Xf[:, _reorder(labels, self.labels_)]
        pos = {m: j for j, m in enumerate(self.labels_)}
        sec = [pos[m] for m in self.coef_.columns]
        F = Xf.shape[0]
        d = (pred - truth).reshape(F, -1, 3)[:, sec]
        return -float(np.sqrt((d ** 2).sum(axis=2)).mean())

    def _predict_A(self, P1, labels) -> pd.DataFrame:
        """The 0.2 prediction: P1 (3F x k) -> 3F x n DataFrame."""
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


def _reorder(labels: list[str], wanted: list[str]) -> list[int]:
    """Columns of a (marker, axis) layout with markers ``labels`` put in ``wanted`` order."""
    pos = {m: j for j, m in enumerate(labels)}
    return [3 * pos[m] + c for m in wanted for c in range(3)]


def _is_label_list(y) -> bool:
    if y is None or isinstance(y, str | np.ndarray | pd.Series | pd.DataFrame):
        return False
    try:
        return len(y) > 0 and all(isinstance(v, str) for v in y)
    except TypeError:
        return False


def _old_predict_form(X, labels, k: int) -> bool:
    if labels is not None:
        return True
    if isinstance(X, pd.DataFrame):
        return not isinstance(X.columns, pd.MultiIndex)
    return np.ndim(X) == 2 and np.shape(X)[1] == k
