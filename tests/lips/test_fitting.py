"""Minimal-force fitting (eqs. 8-10): constraints met, paper's dense formula, least force."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.lips.fem import assemble_stiffness
from facemotion.lips.fitting import MinimalForceFitter, fit_dense_reference, fit_residuals
from facemotion.lips.mesh import parametric_lip_mesh

MESH = parametric_lip_mesh()
K = assemble_stiffness(MESH)
TRACKED = [MESH.labels[i] for i in (0, 3, 6, 9, 12, 15, 18, 21, 96, 99, 102, 105, 108, 111,
                                    114, 117)]
GOALS = np.random.default_rng(7).normal(scale=3.0, size=(25, 16, 3))


def test_constraints_met_and_fixed_nodes_still():
    fitter = MinimalForceFitter(MESH, K, TRACKED)
    U = fitter.fit(GOALS)
    assert U.shape == (25, MESH.n_nodes, 3)
    res = fit_residuals(U, GOALS, fitter.tracked)
    assert res["max_residual_mm"].max() < 1e-10
    assert np.all(U[:, MESH.fixed] == 0)


def test_factorised_path_equals_paper_dense_formula():
    fitter = MinimalForceFitter(MESH, K, TRACKED)
    dense = fit_dense_reference(fitter.K_s.toarray(), fitter.constrained,
                                GOALS.reshape(25, -1))
    U = fitter.fit(GOALS).reshape(25, -1)[:, fitter.dofs]
    np.testing.assert_allclose(U, dense, atol=1e-9 * np.abs(dense).max())


def test_least_force_and_gaussian_conditional_mean():
    fitter = MinimalForceFitter(MESH, K, TRACKED)
    Ks = fitter.K_s.toarray()
    g = GOALS[0].ravel()
    u = fitter.fit(GOALS[:1]).reshape(-1)[fitter.dofs]
    F = Ks @ u
    np.testing.assert_allclose(F, fitter.forces(GOALS[:1])[0], atol=1e-9)
    # any other displacement meeting the goals needs more force
    rng = np.random.default_rng(3)
    for _ in range(5):
        v = rng.normal(scale=0.1, size=len(u))
        v[fitter.constrained] = 0.0          # u + v still meets the goals
        alt = u + v
        assert np.linalg.norm(Ks @ alt) >= np.linalg.norm(F) - 1e-9
    # conditional mean of a Gaussian with covariance K_s^-2 given the constrained DOF
    S = np.linalg.inv(Ks @ Ks)
    c = fitter.constrained
    cond = S[:, c] @ np.linalg.solve(S[np.ix_(c, c)], g)
    np.testing.assert_allclose(u, cond, atol=1e-7 * np.abs(u).max())


def test_tracked_point_not_a_node():
    with pytest.raises(InputError, match="'L999' is not a node"):
        MinimalForceFitter(MESH, K, TRACKED[:-1] + ["L999"])


def test_tracked_point_on_fixed_node():
    fixed_label = MESH.labels[MESH.fixed[0]]
    with pytest.raises(InputError, match=f"tracked point {fixed_label} is on a fixed node"):
        MinimalForceFitter(MESH, K, TRACKED[:-1] + [fixed_label])


def test_repeated_tracked_point_and_bad_goals():
    with pytest.raises(InputError, match="repeated"):
        MinimalForceFitter(MESH, K, TRACKED[:-1] + [TRACKED[0]])
    fitter = MinimalForceFitter(MESH, K, TRACKED)
    with pytest.raises(InputError, match=r"goals must be \(frames, 16, 3\)"):
        fitter.fit(GOALS[:, :15])
    bad = GOALS.copy()
    bad[4, 2, 1] = np.nan
    with pytest.raises(InputError, match=f"{TRACKED[2]} in frame 4"):
        fitter.fit(bad)
