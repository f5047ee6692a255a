"""Marker ranking: three routes vs scipy's pivoted QR, interpolative decomposition, bad input."""

import numpy as np
import pytest
import scipy.linalg
import scipy.linalg.interpolative as sli

from facemotion.errors import InputError
from facemotion.pivoted_qr import (
    epsilon_rank,
    pivoted_cholesky,
    rank_markers,
    tsqr_r,
    update_r,
)


def correlated(F=2000, n=20, sources=5, noise=0.4, seed=0):
    """Displacements of n markers driven by a few smooth sources plus independent noise."""
    rng = np.random.default_rng(seed)
    S = np.cumsum(rng.standard_normal((3 * F, sources)), axis=0) * 0.2
    W = rng.standard_normal((sources, n))
    return S @ W + noise * rng.standard_normal((3 * F, n)), [f"L{j:03d}" for j in range(n)]


@pytest.mark.parametrize("method", ["scipy", "tsqr", "gram", "auto"])
def test_pivots_and_r_match_scipy(method):
    A, labels = correlated()
    R_ref, P_ref = scipy.linalg.qr(A, mode="economic", pivoting=True)[1:]
    rk = rank_markers(A, labels, method=method)
    np.testing.assert_array_equal(rk.order, P_ref)
    # |R| equal up to the sign of each row
    np.testing.assert_allclose(np.abs(rk.R), np.abs(R_ref), atol=1e-9 * np.abs(R_ref).max())
    assert np.all(np.diag(rk.R) >= 0)
    np.testing.assert_allclose(rk.r_rms, np.abs(np.diag(R_ref)) / np.sqrt(A.shape[0]))
    assert rk.labels_in_order == [labels[j] for j in P_ref]
    assert np.all(np.diff(rk.r) <= 1e-9 * rk.r[0])  # non-increasing


def test_selected_set_matches_interpolative_decomposition():
    A, labels = correlated(n=15, seed=3)
    rk = rank_markers(A, labels)
    for k in (1, 4, 8):
        idx, _ = sli.interp_decomp(A, k, rand=False)
        np.testing.assert_array_equal(rk.order[:k], idx[:k])


def test_tsqr_update_equals_one_qr():
    A, _ = correlated(F=700, n=12, seed=5)
    R = None
    for blk in np.array_split(A, 7):
        R = update_r(R, blk)
    np.testing.assert_allclose(R.T @ R, A.T @ A, rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(np.abs(tsqr_r(A, chunk_rows=300)), np.abs(R), atol=1e-8)


def test_pivoted_cholesky_reconstructs_gram_in_pivot_order():
    A, _ = correlated(F=500, n=10, seed=2)
    G = A.T @ A
    piv, Rr = pivoted_cholesky(G)
    R = Rr[:, piv]
    np.testing.assert_allclose(R.T @ R, G[np.ix_(piv, piv)], rtol=1e-10, atol=1e-8)
    assert np.allclose(np.tril(R, -1), 0)


def test_auto_falls_back_to_tsqr_on_copied_marker():
    A, labels = correlated(seed=4)
    A[:, 7] = A[:, 2]  # exact copy: r_kk ~ 0 where Gram accuracy is lost
    rk = rank_markers(A, labels, method="auto")
    assert rk.method == "tsqr"
    assert rk.numerical_rank() == A.shape[1] - 1
    assert rk.r_rms[-1] < 1e-10
    eps = epsilon_rank(rk, [1e-6])
    assert eps.epsilon_rank[0] == A.shape[1] - 1
    assert eps.redundant_markers[0] in ("L002", "L007")


def test_epsilon_rank_counts_and_lists_redundant_markers():
    A, labels = correlated(noise=0.4)
    rk = rank_markers(A, labels)
    df = epsilon_rank(rk, [0.01, 1.0, 1e6])
    assert list(df.columns) == ["tolerance_mm", "epsilon_rank", "redundant_markers"]
    assert df.epsilon_rank.tolist()[0] == 20 and df.redundant_markers[0] == ""
    assert df.epsilon_rank[2] == 0
    k = int(np.sum(rk.r_rms > 1.0))
    assert df.epsilon_rank[1] == k
    assert df.redundant_markers[1] == ",".join(rk.labels_in_order[k:])
    with pytest.raises(InputError, match="tolerances_mm"):
        epsilon_rank(rk, [0.5, -1])


def test_bad_input_errors_name_the_problem():
    A, labels = correlated(F=100, n=10)
    with pytest.raises(InputError, match=r"3 frames .*10 markers"):
        rank_markers(A[:9], labels)
    B = A.copy()
    B[5, 3] = np.nan
    for method in ("auto", "tsqr", "scipy"):
        with pytest.raises(InputError, match="L003"):
            rank_markers(B, labels, method=method)
    B = A.copy()
    B[:, 6] = 0.0
    with pytest.raises(InputError, match="L006 never move"):
        rank_markers(B, labels)
    with pytest.raises(InputError, match="labels"):
        rank_markers(A, labels[:-1])
    with pytest.raises(InputError, match="method"):
        rank_markers(A, labels, method="svd")
