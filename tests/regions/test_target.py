"""k for a target held-out error: the per-sentence sums against per-k least squares, the rule
on planted curves, and the bootstrap interval's two sides."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ranking.routes import rank_markers
from facemotion.regions.prediction import error_curve_naive
from facemotion.regions.target import (
    MIN_SENTENCES,
    SentenceErrors,
    k_for_error,
    sentence_error_sums,
)


def test_sentence_sums_pool_to_the_least_squares_curve():
    rng = np.random.default_rng(1)
    n, F = 12, 900
    W = rng.standard_normal((4, n))
    S = np.cumsum(rng.standard_normal((3 * 2 * F, 4)), axis=0) * 0.2
    AB = S @ W + 0.3 * rng.standard_normal((3 * 2 * F, n))
    A, B = AB[: 3 * F], AB[3 * F:]
    labels = [f"M{j}" for j in range(n)]
    rk = rank_markers(A, labels)
    row_sentence = np.repeat(np.arange(6), 3 * F // 6)
    errs = sentence_error_sums(rk, B, labels, row_sentence, [f"s{i}" for i in range(6)])
    ref = error_curve_naive(A, B, labels, rk)        # one lstsq per k
    ref = ref.set_index("k").loc[errs.ks, "mean_abs_error_mm"].to_numpy()
    np.testing.assert_allclose(errs.pooled_mean(), ref, rtol=1e-9)
    assert errs.sentences == [f"s{i}" for i in range(6)]
    # each sentence alone is the same measure on its own frames
    one = sentence_error_sums(rk, B[: 3 * F // 6], labels, row_sentence[: 3 * F // 6])
    np.testing.assert_allclose(one.sums[0], errs.sums[0], rtol=1e-9)


def planted(curves: np.ndarray, frames: int = 100, n: int = 10) -> SentenceErrors:
    """Per-sentence mean errors ``curves`` (S, K) as SentenceErrors, k = 1..K."""
    S, K = curves.shape
    ks = np.arange(1, K + 1)
    counts = np.tile(frames * (n - ks), (S, 1)).astype(float)
    return SentenceErrors(ks, curves * counts, counts, [str(i) for i in range(S)], n)


def test_k_is_the_first_k_at_or_below_the_target():
    curve = np.array([3.0, 2.0, 1.0, 0.9, 0.5])
    errs = planted(np.tile(curve, (8, 1)))
    assert k_for_error(errs, 1.0).k == 3           # equal to the target counts
    assert k_for_error(errs, 0.95).k == 4
    assert k_for_error(errs, 3.5).k == 1
    # identical sentences: every resample gives the same k
    kt = k_for_error(errs, 1.0)
    assert (kt.k_low, kt.k_high) == (3, 3)
    assert kt.error_at_k_mm == pytest.approx(1.0)
    # not reached within the curve: no k, said as such
    none = k_for_error(errs, 0.1)
    assert none.k is None and "no k up to 5" in none.describe()


def test_the_interval_widens_with_sentence_spread_and_is_censored_honestly():
    rng = np.random.default_rng(0)
    base = np.array([3.0, 2.0, 1.3, 1.05, 0.95, 0.7, 0.5])
    spread = base * (1 + 0.4 * rng.standard_normal((12, 1)))
    kt = k_for_error(planted(spread), 1.0, seed=3)
    assert kt.k_low < kt.k_high                    # the sentences disagree: a real interval
    assert kt.k_low <= kt.k <= kt.k_high
    # a target the pooled curve reaches only at its last k: some resamples never do
    errs = planted(spread)
    last = k_for_error(errs, float(errs.pooled_mean()[-1]) * 1.0001, seed=3)
    assert (last.k, last.k_low, last.k_high) == (7, 7, None)
    assert "interval 7-more" in last.describe()


def test_too_few_sentences_give_no_interval():
    errs = planted(np.tile([2.0, 0.5], (MIN_SENTENCES - 1, 1)))
    kt = k_for_error(errs, 1.0)
    assert kt.k == 2 and kt.k_low is None and kt.k_high is None
    assert "no interval" in kt.describe()


@pytest.mark.parametrize("kw,msg", [({"target_mm": 0.0}, "target error"),
                                    ({"target_mm": float("nan")}, "target error"),
                                    ({"level": 1.0}, "interval level"),
                                    ({"resamples": 0}, "resamples")])
def test_bad_settings_are_refused(kw, msg):
    with pytest.raises(InputError, match=msg):
        k_for_error(planted(np.ones((6, 3))), **kw)
