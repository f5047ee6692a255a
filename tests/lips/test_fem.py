"""Lip thin-shell elements: symmetry, zero modes, scikit-fem reference, patch test, invariances."""

import numpy as np
import pytest
from skfem import Basis, ElementTriP1, ElementVector, MeshTri
from skfem.models.elasticity import linear_elasticity

from facemotion.errors import InputError
from facemotion.lips.fem import (
    assemble_stiffness,
    cst_b_matrix,
    cst_stiffness,
    element_stiffness,
    material_matrix,
    normal_stiffness,
    reduced_stiffness,
)
from facemotion.lips.mesh import parametric_lip_mesh

RNG = np.random.default_rng(1234)


def _zero_modes(K, rel=1e-10):
    w = np.linalg.eigvalsh(K)
    return int(np.sum(np.abs(w) < rel * np.abs(w).max())), w


def _random_triangle(dim):
    while True:
        p = RNG.normal(scale=10.0, size=(3, dim))
        q = np.column_stack([p, np.zeros((3, 3 - dim))])
        area = 0.5 * np.linalg.norm(np.cross(q[1] - q[0], q[2] - q[0]))
        if area > 5.0:
            return p


def test_material_matrix_is_the_plane_strain_matrix():
    E, nu = 2.5, 0.3
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    plane_strain = np.array([[lam + 2 * mu, lam, 0], [lam, lam + 2 * mu, 0], [0, 0, mu]])
    np.testing.assert_allclose(material_matrix(E, nu), plane_strain, rtol=1e-14)


def test_cst_symmetric_psd_with_three_rigid_modes():
    for _ in range(20):
        k = cst_stiffness(_random_triangle(2), E=1.0, nu=0.01)
        np.testing.assert_allclose(k, k.T, atol=1e-14)
        n0, w = _zero_modes(k)
        assert n0 == 3
        assert w.min() > -1e-12 * w.max()


def test_cst_equals_scikit_fem_plane_strain_element():
    E, nu = 1.0, 0.01
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    for _ in range(10):
        xy = _random_triangle(2)
        basis = Basis(MeshTri(xy.T, np.array([[0, 1, 2]]).T), ElementVector(ElementTriP1()))
        ref = linear_elasticity(lam, mu).assemble(basis).toarray()
        order = basis.nodal_dofs.T.ravel()   # (u1, v1, u2, v2, u3, v3)
        np.testing.assert_allclose(cst_stiffness(xy, E, nu), ref[np.ix_(order, order)],
                                   atol=1e-13 * np.abs(ref).max())


def test_element_9x9_zero_modes_are_translations_and_in_plane_rotation():
    p = _random_triangle(3)
    k = element_stiffness(p)
    np.testing.assert_allclose(k, k.T, atol=1e-14)
    n0, w = _zero_modes(k)
    assert n0 == 4 and w.min() > -1e-12 * w.max()
    for axis in np.eye(3):   # translations cost nothing
        assert np.linalg.norm(k @ np.tile(axis, 3)) < 1e-12
    n = np.cross(p[1] - p[0], p[2] - p[0])
    n /= np.linalg.norm(n)
    spin = np.cross(n, p - p.mean(0)).ravel()   # rotation about the normal: free
    assert np.linalg.norm(k @ spin) < 1e-12
    tilt = np.cross(p[1] - p[0], p - p.mean(0)).ravel()   # rotation about an in-plane axis
    assert spin @ k @ spin < 1e-12 < tilt @ k @ tilt


def test_normal_stiffness_has_no_area_factor_and_model_is_unit_free():
    np.testing.assert_allclose(normal_stiffness(1.0, 0.01) @ np.ones(3), 0, atol=1e-15)
    mesh = parametric_lip_mesh()
    K_mm = assemble_stiffness(mesh).toarray()
    K_cm = assemble_stiffness(mesh.with_nodes(mesh.nodes / 10.0)).toarray()
    np.testing.assert_allclose(K_mm, K_cm, atol=1e-12 * np.abs(K_mm).max())


def test_patch_test_linear_field_constant_strain_balanced_interior():
    # flat patch: a node surrounded by 6 triangles; linear in-plane field
    ang = np.arange(6) * np.pi / 3 + 0.2
    pts = np.vstack([[0.3, -0.1], np.column_stack([np.cos(ang), 1.3 * np.sin(ang)]) * 10])
    tris = [[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)]
    A = np.array([[0.01, -0.02], [0.03, 0.015]])
    u = pts @ A.T
    C = material_matrix(1.0, 0.01)
    strain = np.array([A[0, 0], A[1, 1], A[0, 1] + A[1, 0]])
    f = np.zeros(14)
    for t in tris:
        dof = (2 * np.array(t)[:, None] + np.arange(2)).ravel()
        B, _ = cst_b_matrix(pts[t])
        np.testing.assert_allclose(B @ u[t].ravel(), strain, atol=1e-15)  # constant strain
        f[dof] += cst_stiffness(pts[t]) @ u[t].ravel()
    np.testing.assert_allclose(f[:2], 0, atol=1e-14)       # interior node in equilibrium
    # the boundary nodal forces of a constant stress field sum to zero
    np.testing.assert_allclose(f.reshape(-1, 2).sum(0), 0, atol=1e-14)
    assert np.linalg.norm(C @ strain) > 0


def test_node_order_and_rigid_rotation_invariance():
    from scipy.spatial.transform import Rotation
    p = _random_triangle(3)
    k = element_stiffness(p)
    for perm in ([1, 2, 0], [2, 1, 0], [0, 2, 1]):
        idx = (3 * np.array(perm)[:, None] + np.arange(3)).ravel()
        np.testing.assert_allclose(element_stiffness(p[perm]), k[np.ix_(idx, idx)],
                                   atol=1e-13)
    R = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    T = np.kron(np.eye(3), R)
    np.testing.assert_allclose(element_stiffness(p @ R.T + 5.0), T @ k @ T.T, atol=1e-13)


def test_assembled_free_mesh_zero_modes_curved_3_flat_4():
    mesh = parametric_lip_mesh()
    free = mesh.with_nodes(mesh.nodes)
    free.fixed = np.array([], dtype=int)
    assert _zero_modes(assemble_stiffness(free).toarray(), 1e-11)[0] == 3
    flat = mesh.nodes.copy()
    flat[:, 2] = 0.0
    flat_mesh = mesh.with_nodes(flat)
    flat_mesh.fixed = np.array([], dtype=int)
    assert _zero_modes(assemble_stiffness(flat_mesh).toarray(), 1e-11)[0] == 4


def test_reduced_stiffness_is_positive_definite_and_factors_scale():
    mesh = parametric_lip_mesh()
    K_s, dofs = reduced_stiffness(assemble_stiffness(mesh), mesh)
    assert K_s.shape == (3 * (mesh.n_nodes - len(mesh.fixed)),) * 2
    assert np.linalg.eigvalsh(K_s.toarray()).min() > 0
    k1 = assemble_stiffness(mesh, ridge_factor=1.0, strip_factor=1.0)
    k2 = assemble_stiffness(mesh, E=2.0, ridge_factor=1.0, strip_factor=1.0)
    np.testing.assert_allclose(k2.toarray(), 2 * k1.toarray(), atol=1e-14)


@pytest.mark.parametrize("kw", [{"E": 0.0}, {"nu": 0.5}, {"ridge_factor": -1.0}])
def test_bad_material_settings(kw):
    with pytest.raises(InputError, match=next(iter(kw))):
        assemble_stiffness(parametric_lip_mesh(), **kw)


def test_four_grounded_nodes_leave_600_free_dof_and_a_nonsingular_k_s():
    # the paper's P has "all 600 columns" (Sec. 4.1): 612 DOF less 4 grounded nodes (12 DOF)
    mesh = parametric_lip_mesh()
    K = assemble_stiffness(mesh).toarray()
    K_s, dofs = reduced_stiffness(assemble_stiffness(mesh), mesh)
    assert K_s.shape == (600, 600) and len(dofs) == 600
    dense = K_s.toarray()
    # full rank by an SVD, positive definite by a Cholesky factorisation
    assert np.linalg.matrix_rank(dense) == 600
    np.linalg.cholesky(dense)
    # every zero-energy mode of the ungrounded K moves a grounded DOF, so grounding removes it
    n0, _ = _zero_modes(K, 1e-11)
    w, v = np.linalg.eigh(K)
    null = v[:, np.argsort(np.abs(w))[:n0]]
    fixed_dofs = np.setdiff1d(np.arange(612), dofs)
    assert np.linalg.matrix_rank(null[fixed_dofs], tol=1e-8) == n0
    # and a load is carried: K_s u = f solved sparse equals the dense solve
    f = np.random.default_rng(1).normal(size=600)
    import scipy.sparse.linalg as spla
    np.testing.assert_allclose(spla.spsolve(K_s, f), np.linalg.solve(dense, f), rtol=1e-8)


def test_ungrounded_strip_leaves_k_singular():
    # the check above must be able to fail: with nothing grounded K is singular
    mesh = parametric_lip_mesh()
    mesh.fixed = np.array([], dtype=int)
    K_s, _ = reduced_stiffness(assemble_stiffness(mesh), mesh)
    assert np.linalg.matrix_rank(K_s.toarray()) < 612


@pytest.mark.parametrize("grounded", [0, 1, 3, 12])
def test_grounded_nodes_must_be_symmetric_and_fit_the_row(grounded):
    with pytest.raises(InputError, match="grounded"):
        parametric_lip_mesh(grounded=grounded)


def test_whole_far_row_can_still_be_grounded():
    mesh = parametric_lip_mesh(grounded=11)
    assert len(mesh.fixed) == 11 and 3 * len(mesh.free_nodes) == 579
