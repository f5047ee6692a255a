"""How many sentences does the marker ranking need?  (Lucero & Munhall 2008, Sec. IV, Fig. 3)

Sentences are added one at a time and the first ``n_pivots`` pivots of A P = Q R are recomputed
after each addition.  Refactoring the growing matrix at every step costs O(S^2) passes over the
data; instead each sentence's contribution is folded into an n x n summary once:

* ``method="gram"``: G_s = A_s^T A_s per sentence; after s sentences G = G_1 + ... + G_s
  (A^T A is additive over row blocks), and diagonal-pivoting Cholesky of G gives the pivots and
  r_kk (see ``facemotion.ranking.routes``).  Every step of the sweep is then a small batched
  computation on n x n matrices; all S steps are done together.
* ``method="tsqr"``: R <- qr([R; A_s]) (TSQR update), then pivoted QR of the n x n R.
* ``method="auto"``: Gram, falling back to TSQR when some r_kk / r_11 among the requested pivots
  is below ``GRAM_RATIO_LIMIT`` (where the Gram route loses accuracy).

Sentence order is the order of first appearance in ``row_sentence``.
"""

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pandas as pd
import scipy.linalg

from facemotion.errors import InputError
from facemotion.ingest.displacements import sentence_rows
from facemotion.ranking.qr import GRAM_RATIO_LIMIT, pivoted_cholesky, update_r
from facemotion.ranking.result import as_matrix, check_column_norms, check_displacements

SWEEP_COLUMNS = ["n_sentences", "order", "marker", "r_rms", "rows"]


def cumulative(G: np.ndarray, axis: int = 0, overwrite: bool = False) -> np.ndarray:
    """Running sums G_1, G_1 + G_2, ... along ``axis`` (np.cumsum is slow on a leading axis);
    with ``overwrite``, in G itself (a temporary array: no second copy to allocate and fill)."""
    G = np.moveaxis(G, axis, 0)
    out = G if overwrite else np.empty_like(G)
    if not overwrite:
        out[0] = G[0]
    for s in range(1, G.shape[0]):
        np.add(out[s - 1], G[s], out=out[s])
    return np.moveaxis(out, 0, axis)


def _block(A, idx):
    """Rows idx of A; a view when they are contiguous (the usual case)."""
    if idx.size and idx[-1] - idx[0] + 1 == idx.size:
        return A[idx[0] : idx[-1] + 1]
    return A[idx]


def sentence_grams(A, groups, cumulative_sums: bool = False):
    """Per-sentence Gram matrices G_s = A_s^T A_s (S, n, n) and rows per sentence.

    With ``cumulative_sums`` the s-th matrix is G_1 + ... + G_s (A^T A of the first s
    sentences), accumulated in the same pass.
    """
    G = np.empty((len(groups), A.shape[1], A.shape[1]))
    for s, idx in enumerate(groups):
        As = _block(A, idx)
        np.matmul(As.T, As, out=G[s])
        if cumulative_sums and s:
            G[s] += G[s - 1]
    return G, np.array([g.size for g in groups])


def _check_n_pivots(n_pivots, n):
    if isinstance(n_pivots, bool) or not isinstance(n_pivots, int | np.integer) or n_pivots < 1:
        raise InputError(f"n_pivots: must be a positive integer, got {n_pivots!r}")
    if n_pivots > n:
        raise InputError(f"n_pivots: {n_pivots} pivots exceed the {n} markers")
    return int(n_pivots)


def _prepare(A, labels, row_sentence, cumulative_sums=False):
    if row_sentence is None and hasattr(A, "row_sentence"):
        row_sentence = A.row_sentence
    A, labels = as_matrix(A, labels)
    if row_sentence is None:
        raise InputError("row_sentence: the sentence index of each row of A is required")
    check_displacements(A, labels)
    _, groups = sentence_rows(row_sentence, A.shape[0])
    Gs, rows = sentence_grams(A, groups, cumulative_sums)
    total = Gs[-1] if cumulative_sums else Gs.sum(axis=0)
    check_column_norms(A, labels, np.diag(total).copy())
    return A, labels, Gs, rows, groups


def _gram_pivots(Gcum, rows_cum, n_steps):
    """Batched pivoted Cholesky: pivots (b, n_steps) and r_rms (b, n_steps)."""
    piv, Rr = pivoted_cholesky(Gcum, n_steps)
    b = np.arange(piv.shape[0])[:, None]
    r = Rr[b, np.arange(n_steps)[None, :], piv]
    return piv, r / np.sqrt(rows_cum)[:, None], r


def _tidy(piv, r_rms, rows_cum, labels):
    S, m = piv.shape
    return pd.DataFrame(
        {
            "n_sentences": np.repeat(np.arange(1, S + 1), m),
            "order": np.tile(np.arange(1, m + 1), S),
            "marker": np.asarray(labels, dtype=object)[piv.ravel()],
            "r_rms": r_rms.ravel(),
            "rows": np.repeat(rows_cum, m),
        },
        columns=SWEEP_COLUMNS,
        copy=False,
    )


def sentence_sweep(
    A,
    labels: Sequence[str] | None = None,
    row_sentence=None,
    n_pivots: int = 12,
    method: str = "auto",
) -> pd.DataFrame:
    """First ``n_pivots`` pivots after 1, 2, ..., S sentences, in one pass over A.

    Returns a tidy DataFrame: n_sentences (sentences used), order (1-based pivot position),
    marker (label), r_rms (|r_kk| / sqrt(rows), mm), rows (rows of A used).
    """
    if method not in ("auto", "gram", "tsqr"):
        raise InputError(f"method: unknown sweep method {method!r}; use auto, gram or tsqr")
    A, labels, Gcum, rows, groups = _prepare(A, labels, row_sentence, cumulative_sums=True)
    m = _check_n_pivots(n_pivots, A.shape[1])
    rows_cum = np.cumsum(rows)
    if method in ("auto", "gram"):
        piv, r_rms, r = _gram_pivots(Gcum, rows_cum, m)
        if method == "gram" or np.all(r[:, -1] >= GRAM_RATIO_LIMIT * r[:, 0]):
            return _tidy(piv, r_rms, rows_cum, labels)
    piv = np.empty((len(groups), m), dtype=np.intp)
    r_rms = np.empty((len(groups), m))
    R = None
    for s, idx in enumerate(groups):
        R = update_r(R, _block(A, idx))  # R <- qr([R; A_s])
        Rp, order = scipy.linalg.qr(R, mode="r", pivoting=True, check_finite=False)
        piv[s] = order[:m]
        d = np.abs(np.diag(Rp))[:m]
        r_rms[s, : d.size] = d / np.sqrt(rows_cum[s])
        r_rms[s, d.size :] = 0.0
    return _tidy(piv, r_rms, rows_cum, labels)


def sentence_sweep_naive(A, labels, row_sentence, n_pivots: int = 12) -> pd.DataFrame:
    """Reference: scipy pivoted QR of the rows of the first s sentences, for every s."""
    A, labels = as_matrix(A, labels)
    check_displacements(A, labels)
    _, groups = sentence_rows(row_sentence, A.shape[0])
    m = _check_n_pivots(n_pivots, A.shape[1])
    piv = np.empty((len(groups), m), dtype=np.intp)
    r_rms = np.empty((len(groups), m))
    rows_cum = np.cumsum([g.size for g in groups])
    for s in range(len(groups)):
        As = A[np.concatenate(groups[: s + 1])]
        R, order = scipy.linalg.qr(As, mode="r", pivoting=True, check_finite=False)
        piv[s] = order[:m]
        d = np.abs(np.diag(R))[:m]
        r_rms[s, : d.size] = d / np.sqrt(rows_cum[s])
        r_rms[s, d.size :] = 0.0
    return _tidy(piv, r_rms, rows_cum, labels)


# --------------------------------------------------------------------------------------------
# stability over random sentence orders
# --------------------------------------------------------------------------------------------


class StabilityResult(NamedTuple):
    """``settling`` (one row per pivot position) and ``agreement`` (one row per n and k).

    settling columns:
        order: 1-based pivot position; marker, final_r_rms: with all sentences;
        settled_sentences: in the given sentence order, the first n such that for every
            n' >= n the r_rms at this position is within ``tolerance`` (relative) of the
            all-sentence value; 1 if always within;
        settled: False when settled_sentences is the last n (all sentences): the value only
            agrees with itself there, so "settles at the last n" cannot be told from "never
            settles" (censored: not within the sentences measured);
        settled_median, settled_p90, settled_max: the same over the random orders.
    agreement columns:
        n_sentences, k; agreement_fraction: share of random orders whose first k pivots (as a
        set) after n sentences equal the all-sentence first k; given_order_agrees: the same for
        the given order (bool); n_replicates.
    """

    settling: pd.DataFrame
    agreement: pd.DataFrame


def _settled(r_rms, final, tolerance):
    """First n (1-based) after which |v_n' - v_final| <= tol |v_final| for all n' >= n.

    r_rms: (..., S, m); final: (..., m).  Returns (..., m) ints.
    """
    bad = np.abs(r_rms - final[..., None, :]) > tolerance * np.abs(final[..., None, :])
    S = r_rms.shape[-2]
    # index of the last bad n (0-based), -1 if none: settled = last_bad + 2 in 1-based n
    last_bad = S - 1 - np.argmax(bad[..., ::-1, :], axis=-2)
    last_bad = np.where(bad.any(axis=-2), last_bad, -1)
    return last_bad + 2


def stability(
    A,
    labels: Sequence[str] | None = None,
    row_sentence=None,
    n_pivots: int = 12,
    tolerance: float = 0.1,
    k_agree: Sequence[int] = (5, 10),
    n_replicates: int = 1000,
    seed: int = 0,
    chunk: int = 20,
) -> StabilityResult:
    """Settling of r_rms and agreement of the selected markers vs the number of sentences.

    Per-sentence Gram matrices are computed once (one pass over A); each random order
    (``np.random.default_rng(seed).permutation``) then only sums n x n matrices and runs a
    batched pivoted Cholesky for max(n_pivots, max(k_agree)) steps.  See StabilityResult.
    """
    A, labels, Gs, rows, groups = _prepare(A, labels, row_sentence)
    n = A.shape[1]
    m, ks = _checked_settings(n, n_pivots, k_agree, tolerance, n_replicates)
    steps = max([m, *ks])
    S = Gs.shape[0]

    # the given order
    piv0, rr0, _ = _gram_pivots(cumulative(Gs), np.cumsum(rows), steps)
    final_piv, final_r = piv0[-1], rr0[-1, :m]
    settled0 = _settled(rr0[:, :m], final_r, tolerance)
    final_sets = {k: np.sort(final_piv[:k]) for k in ks}
    given_agree = {k: (np.sort(piv0[:, :k], axis=1) == final_sets[k]).all(axis=1) for k in ks}

    # random orders
    rng = np.random.default_rng(seed)
    perms = np.array([rng.permutation(S) for _ in range(int(n_replicates))], dtype=np.intp)
    perms = perms.reshape(int(n_replicates), S)
    settled_rep, agree_count = _random_orders(Gs, rows, perms, steps, final_r, ks, final_sets,
                                              tolerance, chunk)
    nrep = perms.shape[0]

    def q(a, p):
        return np.quantile(a, p, axis=0) if nrep else np.full(m, np.nan)

    settling = pd.DataFrame(
        {
            "order": np.arange(1, m + 1),
            "marker": [labels[j] for j in final_piv[:m]],
            "final_r_rms": final_r,
            "settled_sentences": settled0,
            "settled": settled0 < S,
            "settled_median": q(settled_rep, 0.5),
            "settled_p90": q(settled_rep, 0.9),
            "settled_max": settled_rep.max(axis=0) if nrep else np.full(m, np.nan),
        }
    )
    agreement = pd.DataFrame(
        [
            {
                "n_sentences": s + 1,
                "k": k,
                "agreement_fraction": agree_count[k][s] / nrep if nrep else float("nan"),
                "given_order_agrees": bool(given_agree[k][s]),
                "n_replicates": nrep,
            }
            for k in ks
            for s in range(S)
        ]
    )
    return StabilityResult(settling, agreement)


def _checked_settings(n: int, n_pivots, k_agree, tolerance, n_replicates) -> tuple[int, list]:
    """The number of pivots followed and the k of the agreement, every setting checked."""
    m = _check_n_pivots(n_pivots, n)
    ks = [int(k) for k in k_agree]
    for k in ks:
        if not 1 <= k <= n:
            raise InputError(f"k_agree: {k} is outside 1..{n} markers")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance: must be a positive relative tolerance, got {tolerance!r}")
    if isinstance(n_replicates, bool) or int(n_replicates) < 0:
        raise InputError(f"n_replicates: must be a non-negative integer, got {n_replicates!r}")
    return m, ks


def _random_orders(Gs: np.ndarray, rows: np.ndarray, perms: np.ndarray, steps: int,
                   final_r: np.ndarray, ks: list[int], final_sets: dict, tolerance: float,
                   chunk: int) -> tuple[np.ndarray, dict]:
    """For each sentence order in ``perms``: when each of the first m r_rms settled, and per k
    how many orders' first k pivots after n sentences equal the final set, for every n."""
    S, n = Gs.shape[0], Gs.shape[1]
    m = final_r.size
    settled_rep = np.empty((perms.shape[0], m), dtype=np.intp)
    agree_count = {k: np.zeros(S, dtype=np.int64) for k in ks}
    for start in range(0, perms.shape[0], chunk):
        P = perms[start : start + chunk]
        c = P.shape[0]
        Gcum = cumulative(Gs[P], axis=1, overwrite=True).reshape(c * S, n, n)  # 1..S sentences
        rows_cum = np.cumsum(rows[P], axis=1).reshape(c * S)
        piv, rr, _ = _gram_pivots(Gcum, rows_cum, steps)
        piv = piv.reshape(c, S, steps)
        rr = rr.reshape(c, S, steps)[..., :m]
        settled_rep[start : start + c] = _settled(rr, final_r[None, :].repeat(c, 0), tolerance)
        for k in ks:
            same = (np.sort(piv[..., :k], axis=-1) == final_sets[k]).all(axis=-1)
            agree_count[k] += same.sum(axis=0)
    return settled_rep, agree_count
