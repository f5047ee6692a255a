"""Learned modes (eqs. 11-13) by SVD, covariance and Gram routes; LLSE estimator."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.lips.llse import LLSE, llse_dense, ppca_noise_var
from facemotion.lips.pca import pca_covariance, pca_gram, pca_svd

RNG = np.random.default_rng(11)
# 60 frames of 45 DOF from 6 latent factors plus a little noise
DATA = (RNG.normal(size=(60, 6)) * [5, 4, 3, 2, 1, 0.5]) @ RNG.normal(size=(6, 45)) \
    + 0.05 * RNG.normal(size=(60, 45)) + RNG.normal(size=45)


def test_svd_equals_covariance_and_gram_routes():
    a, b, c = pca_svd(DATA, 10), pca_covariance(DATA, 10), pca_gram(DATA, 10)
    for other in (b, c):
        np.testing.assert_allclose(a.variances, other.variances, rtol=1e-10)
        np.testing.assert_allclose(a.modes, other.modes, atol=1e-8)
        assert a.total_variance == pytest.approx(other.total_variance, rel=1e-12)
    np.testing.assert_allclose(a.modes @ a.modes.T, np.eye(10), atol=1e-12)
    np.testing.assert_allclose(a.variances[0], np.var(
        (DATA - DATA.mean(0)) @ a.modes[0], ddof=1), rtol=1e-12)
    t = a.table()
    assert list(t.columns) == ["mode", "variance", "cumulative_fraction"]
    assert t["mode"].tolist() == list(range(1, 11))
    assert np.all(np.diff(t["cumulative_fraction"]) >= 0) and t["cumulative_fraction"].iloc[-1] < 1
    assert pca_svd(DATA).table()["cumulative_fraction"].iloc[-1] == pytest.approx(1.0)


def test_too_few_frames_for_modes():
    with pytest.raises(InputError, match="n_modes: 10 modes requested but 8 frames"):
        pca_svd(DATA[:8], 10)


def test_llse_factor_route_equals_literal_formula():
    modes = pca_svd(DATA[:50], 10)
    obs = np.arange(0, 45, 3)
    H = np.eye(45)[obs]
    y = DATA[50:, obs]
    for est, cov in ((LLSE.from_modes(modes),
                      modes.modes.T @ np.diag(modes.variances) @ modes.modes),
                     (LLSE.from_data(DATA[:50]), np.cov(DATA[:50].T))):
        np.testing.assert_allclose(est.covariance, cov, atol=1e-10)
        for s2 in (1e-3, 0.1, 2.0):
            np.testing.assert_allclose(est.estimate(y, obs, s2),
                                       llse_dense(y, H, est.mean, cov, s2), atol=1e-8)


def test_llse_tends_to_least_squares_on_modes():
    modes = pca_svd(DATA[:50], 6)
    obs = np.arange(0, 45, 2)   # 23 observed DOF > 6 modes
    y = DATA[50:, obs]
    coef = np.linalg.lstsq(modes.modes.T[obs], (y - modes.mean[obs]).T, rcond=None)[0]
    ls = (modes.mean[:, None] + modes.modes.T @ coef).T
    est = LLSE.from_modes(modes)
    np.testing.assert_allclose(est.estimate(y, obs, 0.0), ls, atol=1e-9)
    err = [np.abs(est.estimate(y, obs, s2) - ls).max() for s2 in (1e-1, 1e-3, 1e-5, 1e-7)]
    assert np.all(np.diff(err) < 0) and err[-1] < 1e-6


def test_full_covariance_exact_on_training_span_without_noise():
    est = LLSE.from_data(DATA[:50])
    obs = np.arange(0, 45)[::1]
    u = est.estimate(DATA[:3, obs], obs, 0.0)
    np.testing.assert_allclose(u, DATA[:3], atol=1e-9)


def test_ppca_noise_var_is_mean_discarded_variance():
    full = pca_svd(DATA[:50])
    s2 = ppca_noise_var(full, 4, 45)
    assert s2 == pytest.approx(full.variances[4:].sum() / (45 - 4), rel=1e-10)
    with pytest.raises(InputError, match="noise_var"):
        LLSE.from_modes(full, 4).estimate(DATA[:1, :3], np.arange(3), -1.0)


def test_noise_free_full_covariance_is_the_conditional_mean_and_minimum_norm():
    # 12 training frames span an 11-dimensional covariance; observe 8 DOF (fewer than its rank):
    # H Lambda H^T is invertible, so sigma^2 = 0 is the literal LLSE formula; and the estimate
    # is the minimum-norm combination of the training deviations that meets the observations
    train = DATA[:12]
    est = LLSE.from_data(train)
    obs = np.array([0, 5, 9, 14, 20, 27, 33, 40])
    H = np.eye(45)[obs]
    y = DATA[50:53, obs]
    u = est.estimate(y, obs, 0.0)
    np.testing.assert_allclose(u, llse_dense(y, H, train.mean(0), np.cov(train.T), 0.0),
                               atol=1e-8)
    np.testing.assert_allclose(u[:, obs], y, atol=1e-9)       # observations met exactly
    X = (train - train.mean(0)).T                               # deviations, (45, 12)
    for f in range(3):
        # independent reference: minimise |c|^2 subject to H X c = r by the KKT system
        A = X[obs]
        r = y[f] - train.mean(0)[obs]
        kkt = np.block([[np.eye(12), A.T], [A, np.zeros((8, 8))]])
        c = np.linalg.solve(kkt, np.concatenate([np.zeros(12), r]))[:12]
        np.testing.assert_allclose(u[f], train.mean(0) + X @ c, atol=1e-8)


def test_both_readings_of_the_10_mode_estimator_against_independent_formulas():
    # 10 modes, 15 observed DOF: H Lambda H^T (15 x 15) has rank 10, the printed inverse does
    # not exist. Pseudo-inverse reading: numpy's pinv of H Lambda H^T in the printed formula.
    # Noise-term reading: the posterior mean in the information form on the mode coefficients,
    # c ~ N(0, diag(lambda)), y = H Phi c + n, n ~ N(0, s2 I):
    # c_hat = (diag(1/lambda) + Phi_o^T Phi_o / s2)^-1 Phi_o^T (y - H m) / s2.
    modes = pca_svd(DATA[:50], 10)
    obs = np.arange(0, 45, 3)
    H = np.eye(45)[obs]
    y = DATA[50:, obs]
    cov = modes.modes.T @ np.diag(modes.variances) @ modes.modes
    S = H @ cov @ H.T
    assert np.linalg.matrix_rank(S) == 10 < len(obs)
    est = LLSE.from_modes(modes)
    r = (y - modes.mean[obs]).T
    pinv = (modes.mean[:, None] + cov @ H.T @ np.linalg.pinv(S, rcond=1e-12) @ r).T
    np.testing.assert_allclose(est.estimate(y, obs, 0.0), pinv, atol=1e-8)
    s2 = ppca_noise_var(pca_svd(DATA[:50]), 10, 45)
    phi_o = modes.modes.T[obs]
    c = np.linalg.solve(np.diag(1 / modes.variances) + phi_o.T @ phi_o / s2, phi_o.T @ r / s2)
    info = (modes.mean[:, None] + modes.modes.T @ c).T
    np.testing.assert_allclose(est.estimate(y, obs, s2), info, atol=1e-8)
    # the two readings differ (the check could fail): the noise term shrinks towards the mean
    gap = np.abs(est.estimate(y, obs, s2) - est.estimate(y, obs, 0.0)).max()
    assert gap > 1e-6
    shrink = np.linalg.norm(est.estimate(y, obs, s2) - modes.mean)
    assert shrink < np.linalg.norm(est.estimate(y, obs, 0.0) - modes.mean)


def test_ppca_noise_var_against_the_covariance_eigenvalues():
    # independent route: eigenvalues of numpy's sample covariance (eq. 13)
    w = np.sort(np.linalg.eigvalsh(np.cov(DATA[:50].T)))[::-1]
    expect = (w.sum() - w[:10].sum()) / (45 - 10)
    assert ppca_noise_var(pca_svd(DATA[:50]), 10, 45) == pytest.approx(expect, rel=1e-9)
