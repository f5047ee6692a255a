"""Sentence sweep (one pass) vs refactoring at every step; stability over random orders."""


import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ranking.stability import (
    sentence_sweep,
    sentence_sweep_naive,
    stability,
)


def sentences(S=12, n=16, seed=0):
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((5, n))
    A, rs = [], []
    for s in range(S):
        F = int(rng.integers(40, 90))
        src = np.cumsum(rng.standard_normal((3 * F, 5)), axis=0) * 0.3
        A.append(src @ W + 0.4 * rng.standard_normal((3 * F, n)))
        rs.append(np.full(3 * F, s))
    return np.vstack(A), [f"S{j}" for j in range(n)], np.concatenate(rs)


@pytest.mark.parametrize("method", ["gram", "tsqr", "auto"])
def test_incremental_sweep_equals_refactoring(method):
    A, labels, rs = sentences()
    fast = sentence_sweep(A, labels, rs, n_pivots=6, method=method)
    naive = sentence_sweep_naive(A, labels, rs, n_pivots=6)
    assert list(fast.columns) == ["n_sentences", "order", "marker", "r_rms", "rows"]
    assert len(fast) == 12 * 6
    assert (fast.marker == naive.marker).all()
    np.testing.assert_allclose(fast.r_rms, naive.r_rms, rtol=1e-8)
    np.testing.assert_array_equal(fast.rows, naive.rows)


def test_stability_tables_and_agreement():
    A, labels, rs = sentences(S=10)
    res = stability(A, labels, rs, n_pivots=6, k_agree=(2, 4), n_replicates=200, seed=1)
    st, ag = res
    final = sentence_sweep_naive(A, labels, rs, n_pivots=6)
    final = final[final.n_sentences == 10]
    assert st.marker.tolist() == final.marker.tolist()
    np.testing.assert_allclose(st.final_r_rms, final.r_rms, rtol=1e-8)
    # agreement is certain with all sentences, a fraction in [0, 1] otherwise
    last = ag[ag.n_sentences == 10]
    assert (last.agreement_fraction == 1.0).all() and last.given_order_agrees.all()
    assert ag.agreement_fraction.between(0, 1).all()
    assert set(ag.k) == {2, 4} and (ag.n_replicates == 200).all()
    assert st.settled_sentences.between(1, 10).all()
    assert (st.settled_max <= 10).all()


def test_settled_sentences_by_hand():
    A, labels, rs = sentences(S=8, seed=3)
    st = stability(A, labels, rs, n_pivots=4, tolerance=0.05, n_replicates=0, k_agree=(2,)).settling
    sw = sentence_sweep_naive(A, labels, rs, n_pivots=4)
    v = sw.pivot(index="n_sentences", columns="order", values="r_rms").to_numpy()
    for i in range(4):
        ok = np.abs(v[:, i] - v[-1, i]) <= 0.05 * v[-1, i]
        expect = next(n for n in range(1, 9) if ok[n - 1 :].all())
        assert st.settled_sentences[i] == expect


def test_bad_input():
    A, labels, rs = sentences(S=3)
    with pytest.raises(InputError, match="row_sentence"):
        sentence_sweep(A, labels, rs[:-3])
    with pytest.raises(InputError, match="n_pivots"):
        sentence_sweep(A, labels, rs, n_pivots=0)
    with pytest.raises(InputError, match="k_agree"):
        stability(A, labels, rs, k_agree=(99,), n_replicates=2)
