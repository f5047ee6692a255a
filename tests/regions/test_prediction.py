"""X = R11^-1 R12 and the all-k held-out error curve vs per-k least squares."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ranking.routes import rank_markers
from facemotion.regions.prediction import (
    error_curve,
    error_curve_naive,
    error_curve_rms,
    fit_coefficients,
    predict,
    residual_norm,
    trajectory_errors,
)


def data(F=1500, n=14, seed=0):
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((4, n))

    def make(F):
        S = np.cumsum(rng.standard_normal((3 * F, 4)), axis=0) * 0.2
        return S @ W + 0.4 * rng.standard_normal((3 * F, n))

    return make(F), make(F // 3), [f"M{j}" for j in range(n)]


def test_coefficients_equal_lstsq_and_residual_norm():
    A, _, labels = data()
    rk = rank_markers(A, labels)
    k = 4
    X = fit_coefficients(rk, k)
    main, sec = rk.order[:k], rk.order[k:]
    X_ref = np.linalg.lstsq(A[:, main], A[:, sec], rcond=None)[0]
    np.testing.assert_allclose(X.to_numpy(), X_ref, rtol=1e-8, atol=1e-10)
    assert list(X.index) == [labels[j] for j in main]
    assert list(X.columns) == [labels[j] for j in sec]
    res = np.linalg.norm(A[:, sec] - A[:, main] @ X_ref)
    assert residual_norm(rk, k) == pytest.approx(res, rel=1e-9)


def test_error_curve_equals_per_k_solves():
    A, B, labels = data()
    rk = rank_markers(A, labels)
    fast = error_curve(rk, B, labels)
    naive = error_curve_naive(A, B, labels, rk)
    num = [c for c in fast.columns if c not in ("main_markers", "pivot_marker")]
    np.testing.assert_allclose(fast[num].to_numpy(), naive[num].to_numpy(), rtol=1e-8, atol=1e-10)
    assert fast.k.tolist() == list(range(1, 15))
    assert fast.iloc[-1].mean_abs_error_mm == 0.0
    assert (fast.main_markers == naive.main_markers).all()
    assert (fast.pivot_marker == fast.main_markers.str.split(",").str[-1]).iloc[:-1].all()
    rms = error_curve_rms(rk, B, labels)
    np.testing.assert_allclose(rms.rms_error_mm, fast.rms_error_mm, rtol=1e-7, atol=1e-9)
    # the error measures relate as they must
    assert (fast.max_abs_error_mm >= fast.mean_abs_error_mm).all()
    # held-out B with shuffled columns gives the same curve (columns matched by label)
    perm = np.random.default_rng(1).permutation(len(labels))
    shuffled = error_curve(rk, B[:, perm], [labels[j] for j in perm])
    np.testing.assert_allclose(shuffled[num].to_numpy(), fast[num].to_numpy())


@pytest.mark.parametrize("k", [2, 3])  # F (n - k) even, then odd: both medians
def test_error_curve_by_hand_for_one_k(k):
    A, B, labels = data(F=1503, n=6)  # 501 held-out frames
    rk = rank_markers(A, labels)
    m, s = rk.order[:k], rk.order[k:]
    X = np.linalg.solve(A[:, m].T @ A[:, m], A[:, m].T @ A[:, s])
    E = (B[:, s] - B[:, m] @ X).reshape(-1, 3, len(s))
    dist = np.sqrt((E**2).sum(axis=1))
    row = error_curve(rk, B, labels).set_index("k").loc[k]
    assert (dist.size % 2 == 0) == (k == 2)
    assert row.mean_abs_error_mm == pytest.approx(dist.mean())
    assert row.median_abs_error_mm == pytest.approx(np.median(dist))
    assert row.max_abs_error_mm == pytest.approx(dist.max())
    assert row.rms_error_mm == pytest.approx(np.sqrt(np.mean(E**2)))
    mag = np.sqrt((B[:, s].reshape(-1, 3, len(s)) ** 2).sum(axis=1))
    assert row.rel_error_pooled == pytest.approx(dist.sum() / mag.sum())
    # Fig. 10 bottom: each marker's mean error over its mean motion, averaged over markers
    per_marker = [dist[:, j].mean() / mag[:, j].mean() for j in range(len(s))]
    assert row.rel_error_per_marker == pytest.approx(np.mean(per_marker))


def test_predict_and_trajectory_errors():
    A, B, labels = data(n=8)
    rk = rank_markers(A, labels)
    P = predict(rk, 3, B)
    assert P.shape == B.shape
    main = rk.order[:3]
    np.testing.assert_array_equal(P[:, main], B[:, main])
    X = np.linalg.lstsq(A[:, main], A, rcond=None)[0]
    np.testing.assert_allclose(P, B[:, main] @ X, rtol=1e-8, atol=1e-8)
    sec = labels[rk.order[5]]
    te = trajectory_errors(B, P, labels, sec)
    j = labels.index(sec)
    err = np.abs(P[:, j] - B[:, j]).reshape(-1, 3)
    np.testing.assert_allclose(te.max_abs_error_mm, err.max(axis=0))
    with pytest.raises(InputError, match="marker"):
        trajectory_errors(B, P, labels, "nope")


def test_k_checks():
    A, B, labels = data(n=6)
    A[:, 5] = A[:, 0] + A[:, 1]
    A[:, 4] = A[:, 2] - A[:, 3]  # rank 4
    rk = rank_markers(A, labels)
    assert rk.numerical_rank() == 4
    with pytest.raises(InputError, match=r"k: 6"):
        fit_coefficients(rk, 6)
    with pytest.raises(InputError, match=r"k: 0"):
        fit_coefficients(rk, 0)
    with pytest.raises(InputError, match=r"k: 5 .*numerical rank 4"):
        fit_coefficients(rk, 5)
    curve = error_curve(rk, B, labels)
    assert curve.k.tolist() == [1, 2, 3, 4, 6]  # up to the rank, then k = n (exact)
    with pytest.raises(InputError, match="M3"):
        error_curve(rk, B[:, [0, 1, 2, 4, 5]], [labels[j] for j in (0, 1, 2, 4, 5)])
