"""MarkerSelector: constrained pivoting against a brute-force greedy rule, prediction vs lstsq."""

import numpy as np
import pandas as pd
import pytest

import facemotion as fm
from facemotion.regions.selector import _A_to_frames, constrained_ranking


def data(F=300, n=8, seed=0):
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(3 * F, 4))
    A = S @ rng.normal(size=(4, n)) * rng.uniform(0.5, 3, n) + 0.3 * rng.normal(size=(3 * F, n))
    return A, [f"m{j}" for j in range(n)]


def brute_force_order(A, labels, force, exclude):
    """At each step, over the allowed group, the column with the largest least-squares residual
    on the columns chosen so far (explicit lstsq, no QR updating)."""
    groups = [list(force), [m for m in labels if m not in force and m not in exclude],
              list(exclude)]
    col = {m: A[:, j] for j, m in enumerate(labels)}
    order, norms = [], []
    for group in groups:
        left = list(group)
        while left:
            best, best_norm = None, -1.0
            for m in left:
                if order:
                    B = np.column_stack([col[o] for o in order])
                    res = col[m] - B @ np.linalg.lstsq(B, col[m], rcond=None)[0]
                else:
                    res = col[m]
                if np.linalg.norm(res) > best_norm:
                    best, best_norm = m, np.linalg.norm(res)
            order.append(best)
            norms.append(best_norm)
            left.remove(best)
    return order, np.array(norms)


@pytest.mark.parametrize("force,exclude", [((), ()), (("m5",), ()), ((), ("m1", "m3")),
                                           (("m6", "m2"), ("m0",))])
def test_constrained_pivoting_equals_brute_force(force, exclude):
    A, labels = data()
    rk = constrained_ranking(A, labels, force=force, exclude=exclude)
    order, norms = brute_force_order(A, labels, force, exclude)
    assert rk.labels_in_order == order
    np.testing.assert_allclose(rk.r, norms, rtol=1e-9)
    # R is a QR factor of A in that order: A[:, order] = Q R, Q orthonormal
    Q = A[:, rk.order] @ np.linalg.inv(rk.R)
    np.testing.assert_allclose(Q.T @ Q, np.eye(len(labels)), atol=1e-9)


def frames(A):
    """A (3F x n) as X: frames x (marker, axis)."""
    return _A_to_frames(A)


def test_without_constraints_it_is_rank_markers():
    A, labels = data(seed=1)
    sel = fm.MarkerSelector(3, center=False, labels=labels).fit(frames(A))
    assert sel.ranking_.labels_in_order == fm.rank_markers(A, labels).labels_in_order
    assert sel.selected_ == sel.ranking_.labels_in_order[:3]


def test_predict_equals_least_squares_on_the_selected_markers():
    A, labels = data(seed=2)
    sel = fm.MarkerSelector(3, force=["m4"], exclude=["m0", "m7"], center=False,
                            labels=labels).fit(frames(A))
    assert "m4" in sel.selected_ and not {"m0", "m7"} & set(sel.selected_)
    B, _ = data(F=50, seed=9)  # new motion
    cols = pd.MultiIndex.from_product([labels, ["x", "y", "z"]], names=["marker", "axis"])
    XB = pd.DataFrame(frames(B), columns=cols)
    pred = sel.predict(XB[sel.selected_[::-1]])  # only the main markers, any order
    assert list(pred.columns) == list(cols)
    idx = [labels.index(m) for m in sel.selected_]
    X = np.linalg.lstsq(A[:, idx], A, rcond=None)[0]  # fit on the training data
    np.testing.assert_allclose(pred.to_numpy(), frames(B[:, idx] @ X),
                               atol=1e-9 * np.abs(B).max())
    np.testing.assert_array_equal(pred[sel.selected_].to_numpy(), XB[sel.selected_].to_numpy())
    # an array with every marker gives the same
    np.testing.assert_allclose(sel.predict(frames(B)), pred.to_numpy())
    np.testing.assert_array_equal(sel.transform(frames(B)), XB[sel.selected_].to_numpy())
    # the 0.2 forms still work, with a warning
    with pytest.warns(DeprecationWarning, match="fit\\(A, labels\\)"):
        old = fm.MarkerSelector(3, force=["m4"], exclude=["m0", "m7"]).fit(A, labels)
    assert old.selected_ == sel.selected_
    with pytest.warns(DeprecationWarning, match="predict\\(P1\\)"):
        p1 = old.predict(B[:, idx])
    np.testing.assert_allclose(p1.to_numpy(), B[:, idx] @ X, atol=1e-9 * np.abs(B).max())


def test_bad_settings():
    A, labels = data()
    X = frames(A)
    with pytest.raises(fm.InputError, match="both forced and excluded"):
        fm.MarkerSelector(2, force=["m1"], exclude=["m1"], labels=labels).fit(X)
    with pytest.raises(fm.InputError, match="m9"):
        fm.MarkerSelector(2, force=["m9"], labels=labels).fit(X)
    with pytest.raises(fm.InputError, match="do not fit"):
        fm.MarkerSelector(1, force=["m1", "m2"], labels=labels).fit(X)
    with pytest.raises(fm.InputError, match="not excluded"):
        fm.MarkerSelector(7, exclude=["m1", "m2"], labels=labels).fit(X)
    with pytest.raises(fm.InputError, match="fit"):
        fm.MarkerSelector(2).predict(X)
    with pytest.raises(ValueError, match="3 per marker"):
        fm.MarkerSelector(2).fit(X[:, :4])
    sel = fm.MarkerSelector(2, labels=labels).fit(X)
    cols = pd.MultiIndex.from_product([["zz"], ["x", "y", "z"]])
    with pytest.raises(fm.InputError, match="lacks main marker"):
        sel.predict(pd.DataFrame(X[:, :3], columns=cols))


def test_selection_table_is_table_one():
    A, labels = data()
    rk = fm.rank_markers(A, labels)
    t = fm.selection_table({"S1": rk, "S2": ["m3", "m1"]}, n=3)
    assert list(t.columns) == ["order", "S1", "S2"]
    assert t["order"].tolist() == [1, 2, 3]
    assert t["S1"].tolist() == rk.labels_in_order[:3]
    assert t["S2"].tolist() == ["m3", "m1", ""]
