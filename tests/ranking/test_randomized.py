"""Randomized selection for many columns vs deterministic pivoted QR (residual within 1.05 x)."""

import logging

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ranking.randomized import selection_residual
from facemotion.ranking.routes import rank_markers
from facemotion.regions.prediction import error_curve_rms


def low_rank_plus_noise(rows=2100, n=2000, rank=200, decay=25.0, noise=0.05, seed=1):
    """Dense: rank-200 with singular values exp(-i / decay), plus Gaussian noise."""
    rng = np.random.default_rng(seed)
    U = rng.standard_normal((rows, rank)) * np.exp(-np.arange(rank) / decay)
    return U @ rng.standard_normal((rank, n)) + noise * rng.standard_normal((rows, n))


@pytest.fixture(scope="module")
def case():
    A = low_rank_plus_noise()
    labels = [f"V{j:04d}" for j in range(A.shape[1])]
    return A, labels, rank_markers(A, labels, method="gram")


def test_pivoted_qr_reference_residual_from_r22(case):
    """selection_residual (one pass over A) equals ||R22||_F of the full factorization."""
    A, _, det = case
    for k in (10, 100):
        assert selection_residual(A, det.order, k) == pytest.approx(
            np.linalg.norm(det.R[k:, k:]), rel=1e-6)


@pytest.mark.parametrize("k", [10, 50, 100])
def test_randomized_residual_within_1_05_of_pivoted_qr(case, k, caplog):
    A, labels, det = case
    with caplog.at_level(logging.INFO, logger="facemotion"):
        rk = rank_markers(A, labels, method="auto", k_max=k)
    assert rk.method == "randomized" and rk.n_ranked == k
    assert "ranking route: randomized" in caplog.text and "exact QR rule" in caplog.text
    ratio = selection_residual(A, rk.order, k) / selection_residual(A, det.order, k)
    assert ratio <= 1.05
    # R's first k rows are A's: the training residual from R equals the direct one
    tail = np.sqrt(np.sum(A * A) - np.sum(rk.R[:k] ** 2))
    assert tail == pytest.approx(selection_residual(A, rk.order, k), rel=1e-6)
    # and the rms curve up to k_max uses them (k, plus the k = n row)
    curve = error_curve_rms(rk, A[:300], labels)
    assert list(curve["k"]) == list(range(1, k + 1)) + [A.shape[1]]


def test_randomized_needs_k_max_and_auto_keeps_gram_without_it():
    A = low_rank_plus_noise(rows=300, n=200)
    labels = [f"V{j}" for j in range(200)]
    with pytest.raises(InputError, match="k_max"):
        rank_markers(A, labels, method="randomized")
    assert rank_markers(A, labels, method="auto").method in ("gram", "tsqr")
    assert rank_markers(A, labels, method="auto", k_max=20).method in ("gram", "tsqr")


def test_route_accuracy_reports_the_ratio_to_pivoted_qr(case, caplog):
    """The study's accuracy check of the randomized route equals the ratio computed here from
    the deterministic ranking of the fixture (the Gram route, scipy's pivots) and is logged."""
    from facemotion.ranking.routes import rank_for_study, route_accuracy

    A, labels, det = case
    rk = rank_for_study(A, labels, "auto", k_max=50)
    assert rk.method == "randomized"
    with caplog.at_level(logging.INFO, logger="facemotion"):
        acc = route_accuracy(A, rk)
    assert acc["k"] == [10, 50]
    expected = [selection_residual(A, rk.order, k) / selection_residual(A, det.order, k)
                for k in (10, 50)]
    np.testing.assert_allclose(acc["ratio"], expected, rtol=1e-9)
    assert max(acc["ratio"]) <= 1.05 and "ratio at k = [10, 50]" in caplog.text
    assert route_accuracy(A[:300, :100], rank_markers(A[:300, :100], labels[:100])) == {
        "k": [], "ratio": []}
