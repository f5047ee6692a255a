"""Linear least-squares estimation (LLSE) of the whole lip shape from partial observations.

Basu & Pentland (1997), Secs. 4.1, 4.2 and 5 (the estimator itself is not numbered): with
observations y = H u + noise (noise variance sigma^2 per observed DOF) and a Gaussian prior on
the displacements u (mean m, covariance Lambda),

    u_hat = m + Lambda H^T (H Lambda H^T + sigma^2 I)^-1 (y - H m).

We write Lambda = L L^T with a thin factor L (D x k): L = Phi diag(sqrt(lambda)) for the k-mode
model, L = X^T / sqrt(F - 1) (centred training data) for the full sample covariance. The
push-through identity gives the same estimate through a k x k system,

    u_hat = m + L (B^T B + sigma^2 I)^-1 B^T (y - H m),   B = H L,

and at sigma^2 = 0 its limit, the minimum-norm least-squares fit u_hat = m + L pinv(B) (y - H m)
(for the k-mode model: least squares on the modes). The paper writes no noise term; with the
10-mode covariance its formula needs one reading or the other (H Lambda H^T has rank 10), and
the study reports both: the noise term with the probabilistic-PCA sigma^2 (the chosen reading,
reasoned in `facemotion.lips.pipeline`) and the pseudo-inverse sigma^2 = 0 beside it.

The noise variance is a setting. The principled default for the k-mode model is probabilistic
PCA (Tipping & Bishop 1999): the variance the k modes leave out, spread evenly over the
remaining D - k directions, sigma^2 = (trace Lambda - sum_{j<=k} lambda_j) / (D - k); it is the
ML isotropic noise of the PPCA model, and it is what an observed DOF contains beyond the k modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facemotion.errors import InputError
from facemotion.lips.pca import Modes


@dataclass
class LLSE:
    """Estimator with prior mean (D,) and covariance factor (D, k); Lambda = factor factor^T."""

    mean: np.ndarray
    factor: np.ndarray

    @classmethod
    def from_modes(cls, modes: Modes, n_modes: int | None = None) -> LLSE:
        """The k-mode model: Lambda = Phi_k diag(lambda_k) Phi_k^T."""
        m = modes if n_modes is None else modes.truncated(n_modes)
        return cls(m.mean, m.modes.T * np.sqrt(np.maximum(m.variances, 0.0)))

    @classmethod
    def from_data(cls, data: np.ndarray) -> LLSE:
        """The full sample covariance of training data (frames, D), exactly (eq. 13)."""
        data = np.asarray(data, dtype=float)
        if len(data) < 2:
            raise InputError(f"LLSE: the full covariance needs at least 2 training frames, "
                             f"got {len(data)}")
        mean = data.mean(axis=0)
        return cls(mean, (data - mean).T / np.sqrt(len(data) - 1))

    @property
    def covariance(self) -> np.ndarray:
        return self.factor @ self.factor.T

    def estimate(self, y: np.ndarray, observed: np.ndarray, noise_var: float) -> np.ndarray:
        """u_hat (frames, D) from y (frames, p), the values of the DOF `observed` (p,)."""
        if not np.isfinite(noise_var) or noise_var < 0:
            raise InputError(f"noise_var: must be >= 0 mm^2, got {noise_var}")
        y = np.atleast_2d(np.asarray(y, dtype=float))
        observed = np.asarray(observed, dtype=int)
        if y.shape[1] != len(observed):
            raise InputError(f"LLSE: {y.shape[1]} observed values per frame but "
                             f"{len(observed)} observed DOF")
        r = (y - self.mean[observed]).T                         # y - H m
        B = self.factor[observed]                               # H L
        if noise_var > 0:
            k = B.shape[1]
            c = np.linalg.solve(B.T @ B + noise_var * np.eye(k), B.T @ r)
        else:
            c = np.linalg.lstsq(B, r, rcond=None)[0]            # sigma^2 -> 0 limit
        return (self.mean[:, None] + self.factor @ c).T


def llse_dense(y: np.ndarray, H: np.ndarray, mean: np.ndarray, cov: np.ndarray,
               noise_var: float) -> np.ndarray:
    """The LLSE formula literally (tests only): m + Lambda H^T (H Lambda H^T + s2 I)^-1 (y - Hm)."""
    y = np.atleast_2d(y)
    S = H @ cov @ H.T + noise_var * np.eye(len(H))
    return (mean[:, None] + cov @ H.T @ np.linalg.solve(S, (y - H @ mean).T)).T


def ppca_noise_var(modes_all: Modes, n_modes: int, dim: int) -> float:
    """Probabilistic-PCA noise variance: mean variance left out by the first n_modes modes
    over the dim - n_modes other directions (Tipping & Bishop 1999, eq. 8)."""
    if n_modes >= dim:
        return 0.0
    kept = float(np.sum(modes_all.variances[:n_modes]))
    return max(modes_all.total_variance - kept, 0.0) / (dim - n_modes)
