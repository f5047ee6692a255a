"""QR subset vs exhaustive optimum (checked by brute force) and greedy selection."""

import itertools

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.regions.optimality import (
    exhaustive_subset,
    greedy_subset,
    projection_residual,
    subset_optimality,
)


def data(F=300, n=10, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3 * F, 4)) @ rng.standard_normal((4, n))
    return A + 0.3 * rng.standard_normal((3 * F, n)), [f"P{j}" for j in range(n)]


@pytest.mark.parametrize("seed", [0, 1])
def test_exhaustive_equals_brute_force(seed):
    A, _ = data(seed=seed)
    G = A.T @ A
    for k in range(1, 6):
        best = min(itertools.combinations(range(10), k), key=lambda S: projection_residual(A, S))
        found, _ = exhaustive_subset(G, k)
        assert projection_residual(A, found) == pytest.approx(projection_residual(A, best))


def test_table_orders_qr_greedy_optimal():
    A, labels = data(n=12)
    df = subset_optimality(A, labels, k_max=4)
    assert list(df.columns) == [
        "k", "qr_subset", "qr_residual_rms_mm", "optimal_subset", "optimal_residual_rms_mm",
        "greedy_subset", "greedy_residual_rms_mm", "qr_over_optimal",
    ]
    tol = 1e-9
    assert (df.optimal_residual_rms_mm <= df.qr_residual_rms_mm + tol).all()
    assert (df.optimal_residual_rms_mm <= df.greedy_residual_rms_mm + tol).all()
    assert (df.qr_over_optimal >= 1 - 1e-9).all()
    # QR residual is ||A - P_S A|| of the first k pivots
    k = 3
    S = [labels.index(x) for x in df.qr_subset[k - 1].split(",")]
    rms = projection_residual(A, S) / np.sqrt(A.shape[0] * (12 - k))
    assert df.qr_residual_rms_mm[k - 1] == pytest.approx(rms)
    # greedy: k = 1 is optimal by construction
    assert df.greedy_residual_rms_mm[0] == pytest.approx(df.optimal_residual_rms_mm[0])


def test_greedy_is_forward_selection():
    A, _ = data(seed=4)
    G = A.T @ A
    chosen = greedy_subset(G, 3)
    for step in range(3):
        prefix = chosen[:step]
        others = [j for j in range(10) if j not in prefix]
        best = min(others, key=lambda j: projection_residual(A, [*prefix, j]))
        assert chosen[step] == best


def test_cap_and_bad_k():
    A, labels = data(n=12)
    with pytest.warns(UserWarning, match="not computed"):
        df = subset_optimality(A, labels, k_max=2, max_subsets=20)
    assert df.optimal_subset[1] == "not computed" and np.isnan(df.optimal_residual_rms_mm[1])
    with pytest.raises(InputError, match="k_max"):
        subset_optimality(A, labels, k_max=12)


def test_projection_residual_equals_least_squares_also_for_a_dependent_subset():
    """The QR route against lstsq's residual; a subset holding a marker and its exact copy
    spans one direction less, which the QR of the subset alone would not see."""
    A, _ = data()
    A = np.column_stack([A, A[:, 3]])  # column 10 = an exact copy of 3
    for S in ([0], [2, 5, 7], [1, 3, 4, 6, 8], [3, 10], [0, 3, 10]):
        X = np.linalg.lstsq(A[:, S], A, rcond=None)[0]
        ref = np.linalg.norm(A - A[:, S] @ X)
        assert projection_residual(A, S) == pytest.approx(ref, rel=1e-12)
    # the copy adds nothing: same residual as without it
    assert projection_residual(A, [0, 3, 10]) == pytest.approx(projection_residual(A, [0, 3]),
                                                               rel=1e-12)
