"""The previous long-gap method, kept as the benchmark's baseline: for each gap, every marker
measured throughout it is a donor, and the model is a thin SVD of the whole take's frames x
3(d + 1) matrix (the method the PCA gap filling replaced)."""

from __future__ import annotations

from unittest import mock

import numpy as np

from facemotion import gaps
from facemotion.errors import InputError


def _pca_fill_svd(pts, long_mask, src, rate, labels, n_donors=None):
    miss = ~np.isfinite(pts).all(axis=2)
    out = pts.copy()
    models: dict[tuple, tuple] = {}
    for j in np.flatnonzero(long_mask.any(axis=0)):
        for a, b in gaps.runs(long_mask[:, j]):
            donors = tuple(int(k) for k in np.flatnonzero(~miss[a:b].any(axis=0)) if k != j)
            key = (int(j), donors)
            if key not in models:
                cols = list(donors) + [int(j)]
                train = np.flatnonzero(~miss[:, cols].any(axis=1))
                if not donors or train.size < gaps.MIN_COMPLETE:
                    raise InputError(f"{src}: marker {labels[j]!r}: cannot reconstruct")
                T = pts[train][:, cols, :].reshape(train.size, -1)
                mu = T.mean(axis=0)
                _, sv, Vt = np.linalg.svd(T - mu, full_matrices=False)
                var = sv ** 2
                k = int(np.searchsorted(np.cumsum(var) / max(var.sum(), 1e-300),
                                        gaps.PCA_VARIANCE) + 1)
                k = min(max(1, min(k, len(sv))), 3 * len(donors))
                models[key] = (mu, Vt[:k].T)
            mu, V = models[key]
            nd = 3 * len(donors)
            xd = pts[a:b][:, list(donors), :].reshape(b - a, nd)
            z, *_ = np.linalg.lstsq(V[:nd], (xd - mu[:nd]).T, rcond=None)
            out[a:b, j, :] = (mu[nd:, None] + V[nd:] @ z).T
    return out


def fill_gaps_svd(rec):
    with mock.patch.object(gaps, "_pca_fill", _pca_fill_svd):
        return gaps.fill_gaps(rec)[0]
