"""Marker ranking: three routes vs scipy's pivoted QR, interpolative decomposition, bad input."""

import numpy as np
import pytest
import scipy.linalg
import scipy.linalg.interpolative as sli

from facemotion.errors import InputError
from facemotion.ranking.epsilon_rank import epsilon_rank, paper_epsilon_rank, r22_norm
from facemotion.ranking.qr import pivoted_cholesky, tsqr_r, update_r
from facemotion.ranking.result import implied_rms_per_coordinate
from facemotion.ranking.routes import rank_markers


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
    df = epsilon_rank(rk, [0.01, 1.0, 1e6], normalisation="per_coordinate")
    assert list(df.columns) == ["tolerance_mm", "r_normalisation", "epsilon_rank",
                                "r22_norm_at_rank_mm", "diagonal_count", "redundant_markers"]
    assert df.epsilon_rank.tolist()[0] == 20 and df.redundant_markers[0] == ""
    assert df.epsilon_rank[2] == 0 and df.diagonal_count[2] == 0
    # the diagonal count is the number of normalised r_kk above the tolerance ...
    assert df.diagonal_count[1] == int(np.sum(rk.r_rms > 1.0))
    # ... and never exceeds the paper's epsilon-rank
    assert (df.diagonal_count <= df.epsilon_rank).all()
    k = int(df.epsilon_rank[1])
    assert df.redundant_markers[1] == ",".join(rk.labels_in_order[k:])
    with pytest.raises(InputError, match="tolerances_mm"):
        epsilon_rank(rk, [0.5, -1])
    with pytest.raises(InputError, match="^normalisation: unknown R normalisation 'size'"):
        epsilon_rank(rk, [0.5], normalisation="size")


def _projected_tail_norm(A, order, k):
    """Independent ||R22||_2: the trailing pivot columns minus their least-squares fit on the
    first k pivot columns (numpy lstsq), as a 2-norm (numpy SVD)."""
    lead, tail = A[:, order[:k]], A[:, order[k:]]
    if k:
        tail = tail - lead @ np.linalg.lstsq(lead, tail, rcond=None)[0]
    return np.linalg.norm(tail, 2) if tail.size else 0.0


def test_r22_norm_against_svd_and_the_singular_value_bound():
    A, labels = correlated(F=300, n=9, sources=4, noise=0.05, seed=7)
    rk = rank_markers(A, labels, method="scipy")
    sigma = np.linalg.svd(A, compute_uv=False)          # descending
    for k in range(0, rk.n + 1):
        ref = _projected_tail_norm(A, rk.order, k)
        assert r22_norm(rk, k) == pytest.approx(ref, rel=1e-9, abs=1e-9)
        if k < rk.n:
            # Sec. III: sigma_{k+1}(A) <= ||R22||_2 (Chan 1987); ||R22||_2 >= |r_{k+1}|
            assert sigma[k] <= r22_norm(rk, k) * (1 + 1e-12)
            assert rk.r[k] <= r22_norm(rk, k) * (1 + 1e-12)
    norms = [r22_norm(rk, k) for k in range(rk.n + 1)]
    assert np.all(np.diff(norms) <= 1e-12 * norms[0])     # non-increasing in k


def test_paper_epsilon_rank_is_the_smallest_k_by_bisection(monkeypatch):
    import facemotion.ranking.epsilon_rank as pq

    A, labels = correlated(F=400, n=40, sources=6, noise=0.05, seed=8)
    rk = rank_markers(A, labels)
    calls = []
    real = pq.spectral_norm
    monkeypatch.setattr(pq, "spectral_norm", lambda M: calls.append(1) or real(M))
    for eps in (1e-3, 0.5, 3.0, 30.0, 1e5):
        calls.clear()
        k, norm = paper_epsilon_rank(rk, eps, "per_coordinate")
        brute = [kk for kk in range(rk.n + 1)
                 if _projected_tail_norm(A, rk.order, kk) / np.sqrt(A.shape[0]) <= eps]
        assert k == min(brute), eps
        assert norm <= eps
        assert len(calls) <= int(np.ceil(np.log2(rk.n + 1)))      # O(log n) 2-norms


def test_normalisation_reading_on_the_papers_quoted_numbers():
    """Fig. 2 of Lucero & Munhall: r56 = 22.70 mm, r57 = 0.10 mm (S1), epsilon = 0.5 mm.

    With ~30 CID sentences of 2-3 s at 120 Hz, A has 3M ~ 20,000-35,000 rows.  Only the
    unnormalised reading makes the 56th pivot's orthogonal component a possible size (an RMS
    of 0.12-0.16 mm per coordinate: marker jitter); per row, 22.70 mm would be more than the
    whole motion of the lower lip, the marker that moves most.  Under it the paper's test
    ||R22||_2 = |r57| = 0.10 <= 0.5 gives epsilon-rank 56, read literally.
    """
    assert pq_default() == "none"
    for rows in (20_000, 27_000, 35_000):
        rms56 = implied_rms_per_coordinate(22.70, rows, "none")
        assert 0.11 < rms56 < 0.17
        assert implied_rms_per_coordinate(0.10, rows, "none") < 1e-3   # an exact copy
        assert implied_rms_per_coordinate(22.70, rows, "per_coordinate") == pytest.approx(22.70)
        assert implied_rms_per_coordinate(22.70, rows, "per_frame") > 10.0
    # the paper's rank test, on an A whose R has the paper's last two diagonal values
    rows, n = 3 * 9000, 57
    rng = np.random.default_rng(0)
    Q, _ = np.linalg.qr(rng.standard_normal((rows, n)))
    diag = np.concatenate([np.geomspace(900.0, 30.0, n - 2), [22.70, 0.10]])
    R = np.diag(diag) + np.triu(rng.normal(0, 0.01, (n, n)), 1) * diag[None, :]
    R[-1, -2] = R[-2, -1] = 0.0
    rk = rank_markers(Q @ R, [str(i) for i in range(1, n + 1)], method="tsqr")
    np.testing.assert_allclose(rk.r[-2:], [22.70, 0.10], rtol=1e-6)
    assert rk.r[-2] / rk.r[-1] == pytest.approx(227.0, rel=1e-5)
    df = epsilon_rank(rk, [0.5])                       # default: the paper's reading
    assert df.epsilon_rank[0] == 56 and df.r22_norm_at_rank_mm[0] == pytest.approx(0.10)
    # per coordinate the same matrix has a much smaller epsilon-rank at 0.5 mm
    assert epsilon_rank(rk, [0.5], normalisation="per_coordinate").epsilon_rank[0] < 56


def pq_default():
    from facemotion.ranking.result import DEFAULT_R_NORMALISATION

    return DEFAULT_R_NORMALISATION


def test_bad_input_errors_name_the_problem():
    A, labels = correlated(F=100, n=10)
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


@pytest.mark.parametrize("method", ["scipy", "tsqr", "gram", "auto"])
def test_fewer_rows_than_markers_ranks_up_to_the_row_count(method, caplog):
    """450 rows for 457 markers (GRID's two-sentence talker): the first 450 pivots are scipy's
    (dgeqp3 on the wide matrix), the other 7 follow with r = 0, and the log says so."""
    rng = np.random.default_rng(4)
    A = rng.standard_normal((450, 30)) @ rng.standard_normal((30, 457))
    A += 0.3 * rng.standard_normal(A.shape)
    labels = [f"L{j:03d}" for j in range(457)]
    R_ref, P_ref = scipy.linalg.qr(A, mode="r", pivoting=True)
    with caplog.at_level("WARNING", logger="facemotion"):
        rk = rank_markers(A, labels, method=method)
    assert "450 rows" in caplog.text and "457 markers" in caplog.text
    assert rk.n_ranked == 450
    np.testing.assert_array_equal(rk.order[:450], P_ref[:450])
    assert sorted(rk.order[450:]) == sorted(set(range(457)) - set(P_ref[:450]))
    np.testing.assert_allclose(rk.r[:450], np.abs(np.diag(R_ref)), rtol=1e-6)
    assert np.all(rk.r[450:] == 0) and np.all(rk.R[450:] == 0)
    assert rk.numerical_rank() == 450


def test_k_max_ranks_only_the_first_pivots():
    A, labels = correlated(F=500, n=40)
    full = rank_markers(A, labels, method="scipy")
    for method in ("gram", "tsqr", "scipy"):
        rk = rank_markers(A, labels, method=method, k_max=12)
        assert rk.n_ranked == 12
        np.testing.assert_array_equal(rk.order[:12], full.order[:12])
        # the first 12 rows of R: the same columns (by label) as the full factorization's
        pos = {lab: i for i, lab in enumerate(full.labels_in_order)}
        cols = [pos[lab] for lab in rk.labels_in_order]
        np.testing.assert_allclose(rk.R[:12], full.R[:12][:, cols],
                                   atol=1e-8 * full.r[0])
        np.testing.assert_allclose(rk.r[:12], full.r[:12], rtol=1e-8)
        assert np.isnan(rk.r[12:]).all()
        assert rk.numerical_rank() == 12


def test_study_route_picks_randomized_only_for_many_markers_with_k_max():
    from facemotion.ranking.routes import RANDOMIZED_MIN_N, study_route

    assert study_route(468, "auto", 100)[0] == "auto"
    assert study_route(RANDOMIZED_MIN_N, "auto", None)[0] == "auto"
    route, why = study_route(RANDOMIZED_MIN_N, "auto", 100)
    assert route == "randomized" and "k_max = 100" in why
    assert study_route(57, "randomized", 10)[0] == "randomized"
    with pytest.raises(InputError, match="^k_max: the randomized route needs k_max"):
        study_route(57, "randomized", None)
    with pytest.raises(InputError, match="^method: unknown ranking method 'fast'"):
        study_route(57, "fast", None)


def test_rank_for_study_ranks_every_marker_below_the_randomized_route(caplog):
    """k_max bounds the curves, not the Gram route's ranking: all r_kk and the epsilon-rank
    are known and equal scipy's."""
    from facemotion.ranking.routes import rank_for_study

    A, labels = correlated(F=300, n=30)
    with caplog.at_level("INFO", logger="facemotion"):
        rk = rank_for_study(A, labels, "auto", k_max=5)
    assert "ranking route: auto" in caplog.text
    assert rk.n_ranked == 30 and np.isfinite(rk.r).all()
    R, P = scipy.linalg.qr(A, mode="r", pivoting=True)
    np.testing.assert_array_equal(rk.order, P)
    np.testing.assert_allclose(rk.r, np.abs(np.diag(R)), rtol=1e-8)
    rr = rank_for_study(A, labels, "randomized", k_max=5)
    assert rr.method == "randomized" and rr.n_ranked == 5 and np.isnan(rr.r[5:]).all()
    t = epsilon_rank(rr, [1e-9, 1e9])  # past k_max ||R22|| is unknown: NaN, never a guess
    assert t["epsilon_rank"].isna().all()
    # the diagonal count over the ranked pivots is a lower bound of the true epsilon-rank
    full = epsilon_rank(rk, [1e-9, 1e9])
    assert (t["diagonal_count"] <= full["epsilon_rank"]).all()


def test_ranking_summary_with_fewer_rows_than_markers():
    """GRID-like: 2 sentences of 10 frames (first frame zero) for 80 markers. The numerical
    rank equals numpy's matrix_rank and the note says how many pivots the QR rule ranked."""
    from facemotion.ranking.routes import ranking_summary

    rng = np.random.default_rng(4)
    blocks = []
    for _ in range(2):
        X = np.cumsum(rng.standard_normal((10, 3, 80)), axis=0)
        blocks.append((X - X[0]).reshape(30, 80))
    A = np.vstack(blocks)
    zero = int(np.count_nonzero(~A.any(axis=1)))
    rk = rank_markers(A, [f"L{j:03d}" for j in range(80)])
    s = ranking_summary(rk, zero)
    assert zero == 6 and s["rows"] == 60 and s["pivots_ranked"] == 60
    assert s["numerical_rank"] == np.linalg.matrix_rank(A) == 54
    assert "at most 54 markers are independent" in s["note"]
    assert "the other 20 markers" in s["note"]
