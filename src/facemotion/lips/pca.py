"""Learned deformation modes (Basu & Pentland 1997, Sec. 4.2, eqs. 11-13).

The covariance of the displacements is K_s^-1 E[F F^T] K_s^-T (eq. 11), K_s^-2 for unit IID
forces (eq. 12); going the other way, the fitted displacements of the training frames, one row
per frame (frames x DOF), give the sample covariance Lambda = X^T X / (F - 1) of the centred
data X (eq. 13; the paper's A = X^T); its eigenvectors are the modes and its eigenvalues their
variances (PCA, Sec. 4.2). We compute them by the SVD of X
(X = U S V^T: modes V, variances S^2 / (F - 1)); the paper's route, an eigen-decomposition of
the covariance (or, cheaper when F < DOF, of the Gram matrix X X^T), is kept for the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError


@dataclass
class Modes:
    """mean (D,), modes (k, D) orthonormal rows, variances (k,), total_variance (trace of the
    sample covariance), n_frames used."""

    mean: np.ndarray
    modes: np.ndarray
    variances: np.ndarray
    total_variance: float
    n_frames: int

    @property
    def n_modes(self) -> int:
        return int(len(self.variances))

    def table(self) -> pd.DataFrame:
        """`mode` (1-based), `variance` (mm^2), `cumulative_fraction` of the total variance."""
        return variance_table(self.variances, self.total_variance)

    def truncated(self, k: int) -> Modes:
        return Modes(self.mean, self.modes[:k], self.variances[:k], self.total_variance,
                     self.n_frames)


def _sign_fix(modes: np.ndarray) -> np.ndarray:
    """Deterministic signs: the largest-magnitude component of each mode is positive."""
    idx = np.argmax(np.abs(modes), axis=1)
    sign = np.sign(modes[np.arange(len(modes)), idx])
    sign[sign == 0] = 1
    return modes * sign[:, None]


def _check(data: np.ndarray, n_modes: int | None, what: str) -> tuple[np.ndarray, int]:
    data = np.asarray(data, dtype=float)
    if data.ndim != 2:
        raise InputError(f"{what}: data must be (frames, DOF), got shape {data.shape}")
    if not np.all(np.isfinite(data)):
        raise InputError(f"{what}: data contain non-finite values")
    f, d = data.shape
    most = min(f - 1, d)
    if n_modes is None:
        n_modes = most
    if n_modes < 1 or n_modes > most:
        raise InputError(f"n_modes: {n_modes} modes requested but {f} frames "
                         f"of {d} DOF support at most {max(most, 0)} (need frames > modes)")
    return data, n_modes


def pca_svd(data: np.ndarray, n_modes: int | None = None) -> Modes:
    """Modes by the SVD of the centred data matrix (frames, DOF). n_modes=None keeps all
    min(frames - 1, DOF)."""
    data, n_modes = _check(data, n_modes, "lip modes")
    mean = data.mean(axis=0)
    X = data - mean                                             # A of eq. 13 (centred)
    _, s, vt = np.linalg.svd(X, full_matrices=False)
    variances = s ** 2 / (len(data) - 1)                        # eigenvalues of eq. 13
    return Modes(mean, _sign_fix(vt[:n_modes]), variances[:n_modes], float(variances.sum()),
                 len(data))


def pca_covariance(data: np.ndarray, n_modes: int | None = None) -> Modes:
    """The paper's route: eigen-decomposition of the sample covariance (eq. 13)."""
    data, n_modes = _check(data, n_modes, "lip modes")
    mean = data.mean(axis=0)
    X = data - mean
    cov = X.T @ X / (len(data) - 1)                             # eq. 13
    w, v = np.linalg.eigh(cov)                                  # PCA, Sec. 4.2
    order = np.argsort(w)[::-1][:n_modes]
    return Modes(mean, _sign_fix(v[:, order].T), w[order], float(np.trace(cov)), len(data))


def pca_gram(data: np.ndarray, n_modes: int | None = None) -> Modes:
    """Same modes from the F x F Gram matrix X X^T: modes = X^T a / sqrt(lambda (F - 1))."""
    data, n_modes = _check(data, n_modes, "lip modes")
    mean = data.mean(axis=0)
    X = data - mean
    gram = X @ X.T / (len(data) - 1)
    w, a = np.linalg.eigh(gram)
    order = np.argsort(w)[::-1][:n_modes]
    w, a = w[order], a[:, order]
    modes = (X.T @ a / np.sqrt(w * (len(data) - 1))).T
    return Modes(mean, _sign_fix(modes), w, float(np.trace(gram)), len(data))


def variance_table(variances: np.ndarray, total: float) -> pd.DataFrame:
    variances = np.asarray(variances, dtype=float)
    return pd.DataFrame({"mode": np.arange(1, len(variances) + 1), "variance": variances,
                         "cumulative_fraction": np.cumsum(variances) / total})
