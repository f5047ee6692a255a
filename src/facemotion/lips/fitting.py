"""Minimal-force fitting of the lip mesh to tracked points (Basu & Pentland 1997, eqs. 8-10).

With U_s = K_s^-1 F_s on the free DOF (eq. 7) and goals U_g for the constrained (tracked) DOF,
P = the rows of K_s^-1 for the constrained DOF (Sec. 4.1): minimising F^T F (eq. 8) subject to
P F = U_g (eq. 9) gives the force of least norm F = P^T (P P^T)^-1 U_g (eq. 10), and the whole
mesh moves by U = K_s^-1 F (eq. 7).

K_s is symmetric, so P^T = K_s^-1 E = G, E selecting the constrained DOF. We factor K_s once
(sparse LU), solve only for the m constrained columns, and never form K_s^-1. With G = Q R
(thin QR), P^T (P P^T)^-1 = G (G^T G)^-1 = Q R^-T, better conditioned than forming G^T G
(whose condition number is that of K_s to the fourth power over the tracked DOF).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from facemotion.errors import InputError
from facemotion.lips.fem import reduced_stiffness
from facemotion.lips.mesh import LipMesh


def tracked_node_indices(mesh: LipMesh, tracked: list[str] | list[int]) -> np.ndarray:
    """Mesh node indices of the tracked points (labels or indices), checked."""
    idx = []
    for t in tracked:
        if isinstance(t, str):
            idx.append(mesh.index(t))
        else:
            i = int(t)
            if not 0 <= i < mesh.n_nodes:
                raise InputError(f"{mesh.name}: tracked node index {i} outside "
                                 f"0..{mesh.n_nodes - 1}")
            idx.append(i)
    idx = np.array(idx, dtype=int)
    if len(idx) == 0:
        raise InputError(f"{mesh.name}: no tracked points given")
    on_fixed = np.isin(idx, mesh.fixed)
    if on_fixed.any():
        bad = mesh.labels[idx[on_fixed][0]]
        raise InputError(f"{mesh.name}: tracked point {bad} is on a fixed node and cannot move")
    if len(set(idx.tolist())) != len(idx):
        dup = sorted({mesh.labels[i] for i in idx if (idx == i).sum() > 1})
        raise InputError(f"{mesh.name}: tracked points repeated: {dup}")
    return idx


class MinimalForceFitter:
    """Fits the mesh to goal displacements of the tracked nodes with least force (eqs. 8-10).

    K is the assembled global stiffness (3N x 3N) of `mesh`. `fit` takes goals (frames, m, 3)
    in the order of `tracked` and returns displacements of every node (frames, N, 3); fixed
    nodes stay at zero.
    """

    def __init__(self, mesh: LipMesh, K: sp.spmatrix, tracked: list[str] | list[int]):
        self.mesh = mesh
        self.tracked = tracked_node_indices(mesh, tracked)
        self.K_s, self.dofs = reduced_stiffness(K, mesh)
        position = -np.ones(3 * mesh.n_nodes, dtype=int)
        position[self.dofs] = np.arange(len(self.dofs))
        self.constrained = position[(3 * self.tracked[:, None] + np.arange(3)).ravel()]
        n, m = len(self.dofs), len(self.constrained)
        lu = spla.splu(self.K_s.tocsc())
        E_sel = np.zeros((n, m))
        E_sel[self.constrained, np.arange(m)] = 1.0
        G = lu.solve(E_sel)                        # P^T = K_s^-1 E (K_s symmetric)
        Q, R = la.qr(G, mode="economic")
        if np.min(np.abs(np.diag(R))) <= 1e-12 * np.max(np.abs(np.diag(R))):
            raise InputError(f"{mesh.name}: the tracked DOF are not independent (P P^T is "
                             f"singular); is the mesh attached to its fixed nodes?")
        self._force_map = Q                        # F = Q R^-T U_g  (eq. 10)
        self._R = R
        self._disp_map = lu.solve(Q)               # U = K_s^-1 F    (eq. 7)

    def forces(self, goals: np.ndarray) -> np.ndarray:
        """Minimal nodal forces on the free DOF, (frames, n_free_dof)."""
        g = self._goals(goals)
        return (self._force_map @ la.solve_triangular(self._R, g, trans="T")).T

    def fit(self, goals: np.ndarray) -> np.ndarray:
        g = self._goals(goals)
        coef = la.solve_triangular(self._R, g, trans="T")   # R^-T U_g
        u_free = self._disp_map @ coef                        # K_s^-1 P^T (P P^T)^-1 U_g
        frames = g.shape[1]
        U = np.zeros((frames, 3 * self.mesh.n_nodes))
        U[:, self.dofs] = u_free.T
        return U.reshape(frames, self.mesh.n_nodes, 3)

    def _goals(self, goals: np.ndarray) -> np.ndarray:
        goals = np.asarray(goals, dtype=float)
        if goals.ndim == 2:
            goals = goals[None]
        m = len(self.tracked)
        if goals.shape[1:] != (m, 3):
            raise InputError(f"{self.mesh.name}: goals must be (frames, {m}, 3) for the "
                             f"{m} tracked points, got {goals.shape}")
        if not np.all(np.isfinite(goals)):
            f, j = np.argwhere(~np.isfinite(goals).all(axis=2))[0]
            raise InputError(f"{self.mesh.name}: goal of tracked point "
                             f"{self.mesh.labels[self.tracked[j]]} in frame {f} is not finite")
        return goals.reshape(len(goals), 3 * m).T


def fit_dense_reference(K_s: np.ndarray, constrained: np.ndarray,
                        goals: np.ndarray) -> np.ndarray:
    """The paper's formula literally, with the explicit inverse (tests only).

    K_s dense (n, n); constrained DOF indices into K_s (m,); goals (frames, m).
    Returns displacements of the free DOF (frames, n).
    """
    K_inv = np.linalg.inv(K_s)
    P = K_inv[constrained, :]                                   # P, Sec. 4.1
    F = P.T @ np.linalg.inv(P @ P.T) @ np.asarray(goals).T     # eq. 10
    return (K_inv @ F).T                                        # eq. 7


def fit_residuals(U: np.ndarray, goals: np.ndarray, tracked: np.ndarray) -> pd.DataFrame:
    """Per frame: max and RMS distance (mm) between fitted tracked nodes and their goals."""
    d = np.linalg.norm(U[:, tracked, :] - goals, axis=2)
    return pd.DataFrame({"frame": np.arange(len(U)), "max_residual_mm": d.max(axis=1),
                         "rms_residual_mm": np.sqrt((d ** 2).mean(axis=1))})
