"""Rigid head alignment: remove the head's motion so only facial deformation is left.

For each frame the head markers present are fitted onto a neutral reference configuration by
the least-squares rotation and translation (Kabsch 1976, Acta Cryst. A32:922):

    H = sum_i (x_i - x_bar)(y_i - y_bar)^T,   H = U S V^T,
    R = V diag(1, 1, det(V U^T)) U^T,         t = y_bar - R x_bar,

which minimises sum_i |R x_i + t - y_i|^2 over proper rotations (the det term excludes
reflections). The same (R, t) is applied to every marker of the frame, so the head markers sit
on the reference and the others move only by deformation. The residual of a frame is the RMS
distance of its fitted head markers from the reference after the fit.
"""

from __future__ import annotations

import numpy as np

from facemotion.errors import InputError
from facemotion.io.recording import Recording, finite_samples

# Centred head markers with s2 / s1 below this (singular values) are taken as collinear:
# the rotation about their line would be undetermined.
COLLINEAR_TOL = 1e-3


def _kabsch_batch(X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid fits for a stack: X, Y (B, m, 3) -> R (B, 3, 3), t (B, 3) with Y ~ X R^T + t."""
    xb = X.mean(axis=1)
    yb = Y.mean(axis=1)
    H = np.einsum("bmi,bmj->bij", X - xb[:, None, :], Y - yb[:, None, :])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.matmul(Vt.transpose(0, 2, 1), U.transpose(0, 2, 1))))
    d[d == 0] = 1.0
    D = np.zeros_like(H)
    D[:, 0, 0] = 1.0
    D[:, 1, 1] = 1.0
    D[:, 2, 2] = d
    R = Vt.transpose(0, 2, 1) @ D @ U.transpose(0, 2, 1)
    t = yb - np.einsum("bij,bj->bi", R, xb)
    return R, t


def _collinear_frames(X: np.ndarray) -> np.ndarray:
    """Indices of the frames of X (B, m, 3) whose centred points have singular values
    s2 < COLLINEAR_TOL * s1, in order.

    The SVD is needed only for frames a cheap bound cannot clear. With C = Xc^T Xc (3 x 3)
    and its eigenvalues l1 >= l2 >= l3 >= 0 (l_i = s_i^2), the sum of C's principal 2 x 2
    minors is e2 = l1 l2 + l1 l3 + l2 l3 <= 3 l1 l2 and l1 <= tr C, so
    l2 / l1 >= e2 / (3 (tr C)^2). Frames with e2 > 6 COLLINEAR_TOL^2 (tr C)^2 thus have
    s2 / s1 >= sqrt(2) COLLINEAR_TOL (the factor 2 is far above the rounding of e2 and of the
    SVD, about 1e-15 here), and the SVD would clear them too; the others are decided by the
    SVD as before, so the frames found are the same.
    """
    Xc = X - X.mean(axis=1, keepdims=True)
    C = np.einsum("bmi,bmj->bij", Xc, Xc)
    tr = C[:, 0, 0] + C[:, 1, 1] + C[:, 2, 2]
    e2 = (C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] ** 2 + C[:, 0, 0] * C[:, 2, 2] - C[:, 0, 2] ** 2
          + C[:, 1, 1] * C[:, 2, 2] - C[:, 1, 2] ** 2)
    unclear = np.flatnonzero(~(e2 > 6.0 * COLLINEAR_TOL ** 2 * tr ** 2))
    if unclear.size == 0:
        return unclear
    s = np.linalg.svd(Xc[unclear], compute_uv=False)
    return unclear[s[:, 1] < COLLINEAR_TOL * s[:, 0]]


def _is_collinear(P: np.ndarray) -> bool:
    """True when points P (m, 3) are (numerically) on one line or fewer than 3."""
    if P.shape[0] < 3:
        return True
    s = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    return bool(s[0] == 0 or s[1] < COLLINEAR_TOL * s[0])


def rigid_fit(source, target) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation R (3, 3) and translation t (3,) with target ~ source @ R.T + t.

    source, target: (m, 3) corresponding points, m >= 3, finite. Proper rotation (det +1)
    even when the best orthogonal map would be a reflection.
    """
    X = np.asarray(source, dtype=float)
    Y = np.asarray(target, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or X.shape != Y.shape:
        raise InputError(f"rigid_fit: source {X.shape} and target {Y.shape} must both be (m, 3)")
    if X.shape[0] < 3:
        raise InputError(f"rigid_fit: need at least 3 points, got {X.shape[0]}")
    if not (np.isfinite(X).all() and np.isfinite(Y).all()):
        raise InputError("rigid_fit: source and target must be finite (no NaN)")
    R, t = _kabsch_batch(X[None], Y[None])
    return R[0], t[0]


def align_head(rec: Recording, head_markers: list[str], reference=None
               ) -> tuple[Recording, np.ndarray]:
    """Remove rigid head motion from ``rec``.

    head_markers: labels of >= 3 markers that barely deform (forehead, nose bridge, ...).
    reference: (m, 3) neutral configuration of the head markers in mm; default: the first frame
        of ``rec`` in which all head markers are present.
    Returns the aligned recording (all markers moved by each frame's fit, NaN kept, fill mask
    kept) and the per-frame RMS residual (frames,) in mm of the fitted head markers.
    Frames where fewer than 3 head markers are present, or where the present ones are
    collinear, raise InputError naming the frame and the missing markers.
    """
    out, residual, _, _ = align_head_transforms(rec, head_markers, reference)
    return out, residual


def align_head_transforms(rec: Recording, head_markers: list[str], reference=None
                          ) -> tuple[Recording, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`align_head`, also returning each frame's fit R (F, 3, 3) and t (F, 3), with
    head frame = lab @ R^T + t (so lab = (head frame - t) @ R)."""
    src = rec.source or "recording"
    head_markers = [str(h) for h in head_markers]
    if len(head_markers) < 3:
        raise InputError(f"{src}: {len(head_markers)} head marker(s) given "
                         f"({', '.join(head_markers) or 'none'}); at least 3 are needed")
    if len(set(head_markers)) != len(head_markers):
        raise InputError(f"{src}: head markers listed twice: {', '.join(head_markers)}")
    idx = [rec.index(h) for h in head_markers]
    head = np.take(rec.points, idx, axis=1)  # (F, m, 3)
    present = finite_samples(head)  # (F, m)
    if reference is None:
        complete = np.flatnonzero(present.all(axis=1))
        if complete.size == 0:
            raise InputError(f"{src}: no frame has all head markers {', '.join(head_markers)} "
                             "(needed for the default reference)")
        ref = head[complete[0]].copy()
    else:
        ref = np.asarray(reference, dtype=float)
        if ref.shape != (len(idx), 3):
            raise InputError(f"{src}: head reference has shape {ref.shape}, expected "
                             f"({len(idx)}, 3) for head markers {', '.join(head_markers)}")
        if not np.isfinite(ref).all():
            raise InputError(f"{src}: head reference has NaN coordinates")
    if _is_collinear(ref):
        raise InputError(f"{src}: head markers {', '.join(head_markers)} are collinear in the "
                         "reference; the head's rotation is undetermined")

    R, t, residual = head_transforms(rec, head_markers, idx, head, present, ref)
    aligned = np.matmul(rec.points, R.transpose(0, 2, 1))  # x R^T per frame (batched)
    aligned += t[:, None, :]
    out = Recording(list(rec.labels), aligned, rec.rate, rec.source, rec.filled.copy())
    return out, residual, R, t


def head_transforms(rec: Recording, head_markers: list[str], idx, head, present, ref
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each frame's rigid fit of the head markers to the reference: R (F, 3, 3), t (F, 3)
    with head-frame = lab @ R^T + t, and the fit's RMS residual (F,) in mm."""
    src = rec.source or "recording"
    F = rec.n_frames
    R = np.empty((F, 3, 3))
    t = np.empty((F, 3))
    residual = np.empty(F)
    # Frames with the same set of present head markers are fitted together in one batch.
    # (a pattern as one integer, first marker the most significant bit: the same order as
    # np.unique of the rows, without its sort of whole rows)
    m = present.shape[1]
    weights = np.array([1 << (m - 1 - j) for j in range(m)], dtype=object if m > 62 else np.int64)
    codes, inverse = np.unique(present.astype(weights.dtype) @ weights, return_inverse=True)
    for k in range(codes.size):
        frames = np.flatnonzero(inverse.ravel() == k)
        pattern = present[frames[0]]  # the frames of group k share it
        cols = np.flatnonzero(pattern)
        if cols.size < 3:
            f = int(frames[0])
            lacking = [head_markers[j] for j in np.flatnonzero(~pattern)]
            raise InputError(f"{src}: frame {f} (t = {f / rec.rate:.3f} s) has only "
                             f"{cols.size} of the head markers; missing {', '.join(lacking)} "
                             f"(at least 3 are needed; {frames.size} frame(s) like this)")
        X = head[frames][:, cols, :]
        Y = np.broadcast_to(ref[cols], X.shape)
        bad = _collinear_frames(X)
        if bad.size:
            f = int(frames[bad[0]])
            names = ", ".join(head_markers[j] for j in cols)
            raise InputError(f"{src}: frame {f} (t = {f / rec.rate:.3f} s): head markers "
                             f"{names} are collinear; the head's rotation is undetermined")
        Rb, tb = _kabsch_batch(X, Y)
        R[frames] = Rb
        t[frames] = tb
        fitted = np.einsum("bij,bmj->bmi", Rb, X) + tb[:, None, :]
        residual[frames] = np.sqrt(np.mean(np.sum((fitted - Y) ** 2, axis=2), axis=1))
    return R, t, residual
