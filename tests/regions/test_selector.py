"""MarkerSelector: constrained pivoting against a brute-force greedy rule, prediction vs lstsq."""

import numpy as np
import pandas as pd
import pytest

import facemotion as fm
from facemotion.regions.selector import constrained_ranking


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


def test_without_constraints_it_is_rank_markers():
    A, labels = data(seed=1)
    sel = fm.MarkerSelector(3).fit(A, labels)
    assert sel.ranking_.labels_in_order == fm.rank_markers(A, labels).labels_in_order
    assert sel.selected_ == sel.ranking_.labels_in_order[:3]


def test_predict_equals_least_squares_on_the_selected_markers():
    A, labels = data(seed=2)
    sel = fm.MarkerSelector(3, force=["m4"], exclude=["m0", "m7"]).fit(A, labels)
    assert "m4" in sel.selected_ and not {"m0", "m7"} & set(sel.selected_)
    B, _ = data(F=50, seed=9)  # new motion
    P1 = pd.DataFrame(B, columns=labels)[sel.selected_[::-1]]  # any column order
    pred = sel.predict(P1)
    assert list(pred.columns) == labels
    idx = [labels.index(m) for m in sel.selected_]
    X = np.linalg.lstsq(A[:, idx], A, rcond=None)[0]  # fit on the training data
    np.testing.assert_allclose(pred.to_numpy(), B[:, idx] @ X, atol=1e-9 * np.abs(B).max())
    np.testing.assert_array_equal(pred[sel.selected_].to_numpy(), B[:, idx])
    # an array in selected_ order gives the same
    np.testing.assert_allclose(sel.predict(B[:, idx]).to_numpy(), pred.to_numpy())


def test_bad_settings():
    A, labels = data()
    with pytest.raises(fm.InputError, match="both forced and excluded"):
        fm.MarkerSelector(2, force=["m1"], exclude=["m1"]).fit(A, labels)
    with pytest.raises(fm.InputError, match="m9"):
        fm.MarkerSelector(2, force=["m9"]).fit(A, labels)
    with pytest.raises(fm.InputError, match="do not fit"):
        fm.MarkerSelector(1, force=["m1", "m2"]).fit(A, labels)
    with pytest.raises(fm.InputError, match="not excluded"):
        fm.MarkerSelector(7, exclude=["m1", "m2"]).fit(A, labels)
    with pytest.raises(fm.InputError, match="fit"):
        fm.MarkerSelector(2).predict(A[:, :2])
    sel = fm.MarkerSelector(2).fit(A, labels)
    with pytest.raises(fm.InputError, match="lacks main marker"):
        sel.predict(pd.DataFrame(A[:, :1], columns=["zz"]))


def test_selection_table_is_table_one():
    A, labels = data()
    rk = fm.rank_markers(A, labels)
    t = fm.selection_table({"S1": rk, "S2": ["m3", "m1"]}, n=3)
    assert list(t.columns) == ["order", "S1", "S2"]
    assert t["order"].tolist() == [1, 2, 3]
    assert t["S1"].tolist() == rk.labels_in_order[:3]
    assert t["S2"].tolist() == ["m3", "m1", ""]
