"""Thin-shell finite elements of the lip mesh (Basu & Pentland 1997, Sec. 2.3).

Each triangle is a flat shell element with 3 DOF per node: in its own 2-D frame a constant-strain
triangle (CST) for the in-plane displacements (u, v) and a separate 3x3 term for the normal
displacement w, decoupled from the in-plane part (paper eqs. 2 and 6; K U = F is eq. 1). The
9x9 local matrix is rotated into global coordinates and assembled into a sparse K; global DOF of
node i are 3 i + (0, 1, 2) = (x, y, z).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from facemotion.errors import InputError
from facemotion.lips.mesh import LipMesh


def material_matrix(E: float = 1.0, nu: float = 0.01) -> np.ndarray:
    """The paper's material matrix C (eq. 5), as printed.

    C = E (1 - v) / ((1 + v)(1 - 2 v)) [[1, v/(1-v), 0], [v/(1-v), 1, 0],
                                        [0, 0, (1 - 2v)/(2(1 - v))]].
    This is the plane-STRAIN matrix, although the paper's text says plane stress; we implement
    the printed formula (at v = 0.01 the two differ by about 1e-4 relative). Engineering shear
    strain (gamma_xy = du/dy + dv/dx).
    """
    _check_material(E, nu)
    pre = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    r = nu / (1 - nu)
    return pre * np.array([[1.0, r, 0.0], [r, 1.0, 0.0],
                           [0.0, 0.0, (1 - 2 * nu) / (2 * (1 - nu))]])


def _check_material(E: float, nu: float) -> None:
    if not np.isfinite(E) or E <= 0:
        raise InputError(f"E: Young's modulus must be positive, got {E}")
    if not np.isfinite(nu) or not -1 < nu < 0.5:
        raise InputError(f"nu: Poisson's ratio must be in (-1, 0.5), got {nu}")


def cst_b_matrix(xy: np.ndarray) -> tuple[np.ndarray, float]:
    """Strain-displacement matrix B (3x6) and area A of a triangle with 2-D corners xy (3, 2).

    strain = B d with d = (u1, v1, u2, v2, u3, v3); b_i = y_j - y_k, c_i = x_k - x_j.
    """
    x, y = xy[:, 0], xy[:, 1]
    b = np.array([y[1] - y[2], y[2] - y[0], y[0] - y[1]])
    c = np.array([x[2] - x[1], x[0] - x[2], x[1] - x[0]])
    area2 = x[1] * y[2] - x[2] * y[1] - x[0] * y[2] + x[2] * y[0] + x[0] * y[1] - x[1] * y[0]
    if abs(area2) <= 0:
        raise InputError("lip FEM: degenerate triangle (zero area)")
    B = np.zeros((3, 6))
    B[0, 0::2] = b
    B[1, 1::2] = c
    B[2, 0::2] = c
    B[2, 1::2] = b
    return B / area2, abs(area2) / 2


def cst_stiffness(xy: np.ndarray, E: float = 1.0, nu: float = 0.01,
                  thickness: float = 1.0) -> np.ndarray:
    """In-plane 6x6 CST stiffness k_xy = t A B^T C B (the k_xy block of eq. 2; strains eq. 3,
    element DOF eq. 4, C eq. 5), DOF (u1, v1, ..., v3)."""
    B, area = cst_b_matrix(np.asarray(xy, dtype=float))
    return thickness * area * B.T @ material_matrix(E, nu) @ B  # k_xy of eq. 2


def normal_stiffness(E: float = 1.0, nu: float = 0.01) -> np.ndarray:
    """Out-of-plane 3x3 k_z (paper eq. 6): the prefactor of C times [[1,-.5,-.5],...].

    No area factor: with one the model would depend on the length unit. Null space: equal
    normal displacement of the three nodes (a translation along the normal).
    """
    _check_material(E, nu)
    pre = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    return pre * (1.5 * np.eye(3) - 0.5 * np.ones((3, 3)))  # eq. 6


def element_frame(p: np.ndarray) -> np.ndarray:
    """Rows e1, e2, n of the element's own frame: e1 along edge 1->2, n the unit normal."""
    e1 = p[1] - p[0]
    n = np.cross(e1, p[2] - p[0])
    e1 = e1 / np.linalg.norm(e1)
    n = n / np.linalg.norm(n)
    return np.vstack([e1, np.cross(n, e1), n])


def element_stiffness(p: np.ndarray, E: float = 1.0, nu: float = 0.01,
                      thickness: float = 1.0) -> np.ndarray:
    """Global 9x9 stiffness of a triangle with 3-D corners p (3, 3), DOF (x1, y1, z1, ...)."""
    p = np.asarray(p, dtype=float)
    R = element_frame(p)
    xy = (p - p[0]) @ R[:2].T
    k_local = np.zeros((9, 9))
    inplane = np.array([0, 1, 3, 4, 6, 7])
    k_local[np.ix_(inplane, inplane)] = cst_stiffness(xy, E, nu, thickness)
    normal = np.array([2, 5, 8])
    k_local[np.ix_(normal, normal)] = normal_stiffness(E, nu)
    T = np.kron(np.eye(3), R)  # d_local = T d_global
    return T.T @ k_local @ T


def assemble_stiffness(mesh: LipMesh, E: float = 1.0, nu: float = 0.01,
                       ridge_factor: float = 2.0, strip_factor: float = 0.5,
                       thickness: float = 1.0) -> sp.csr_matrix:
    """Global stiffness K (3N x 3N, scipy CSR) of the whole mesh, fixed nodes included.

    Element kinds scale E: ridge elements by `ridge_factor` (2 in the paper), strip elements by
    `strip_factor` (the paper says only "soft"; 0.5 is our choice).
    """
    for name, val in (("ridge_factor", ridge_factor), ("strip_factor", strip_factor),
                      ("thickness", thickness)):
        if not np.isfinite(val) or val <= 0:
            raise InputError(f"{name}: must be positive, got {val}")
    factors = mesh.stiffness_factors(ridge_factor, strip_factor)
    rows, cols, vals = [], [], []
    for t, tri in enumerate(mesh.triangles):
        ke = element_stiffness(mesh.nodes[tri], E * factors[t], nu, thickness)
        dof = (3 * tri[:, None] + np.arange(3)).ravel()
        rows.append(np.repeat(dof, 9))
        cols.append(np.tile(dof, 9))
        vals.append(ke.ravel())
    n = 3 * mesh.n_nodes
    K = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    return ((K + K.T) * 0.5).tocsr()


def free_dofs(mesh: LipMesh) -> np.ndarray:
    """Global DOF indices of the free (not fixed) nodes, ascending."""
    return (3 * mesh.free_nodes[:, None] + np.arange(3)).ravel()


def reduced_stiffness(K: sp.spmatrix, mesh: LipMesh) -> tuple[sp.csc_matrix, np.ndarray]:
    """K_s: K with the fixed nodes' rows and columns removed, and the kept global DOF."""
    dofs = free_dofs(mesh)
    K = sp.csr_matrix(K)
    return K[dofs][:, dofs].tocsc(), dofs
