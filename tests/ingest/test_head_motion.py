"""Rigid head alignment against planted rotations, scipy's Rotation, and bad input."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.ingest.head_motion import align_head, rigid_fit
from facemotion.io.recording import Recording

HEAD = ["ForeHead_M", "ForeHead_L", "ForeHead_R", "NoseTop"]


def planted(F=200, noise=0.0, seed=0):
    """Face in head coordinates (head markers rigid, others deforming), then moved per frame."""
    rng = np.random.default_rng(seed)
    head = np.array([[0, 80, 40], [-40, 75, 30], [40, 75, 30], [0, 30, 60]], dtype=float)
    face0 = rng.uniform(-50, 50, size=(6, 3))
    t = np.arange(F) / 60.0
    face = face0 + 3 * np.sin(2 * np.pi * 1.5 * t)[:, None, None] * rng.standard_normal((6, 3))
    true = np.concatenate([np.broadcast_to(head, (F, 4, 3)), face], axis=1)
    R = Rotation.random(F, random_state=seed).as_matrix()
    shift = rng.uniform(-200, 200, size=(F, 3))
    moved = np.einsum("fij,fmj->fmi", R, true) + shift[:, None, :]
    moved[:, :4] += noise * rng.standard_normal((F, 4, 3))
    labels = HEAD + [f"M{i}" for i in range(6)]
    return Recording(labels, moved, 60.0, source="planted.c3d"), true, head


def test_rigid_fit_recovers_planted_motion_and_matches_scipy():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((7, 3)) * 50
    R_true = Rotation.random(random_state=4).as_matrix()
    t_true = np.array([10.0, -5.0, 3.0])
    Y = X @ R_true.T + t_true
    R, t = rigid_fit(X, Y)
    np.testing.assert_allclose(R, R_true, atol=1e-12)
    np.testing.assert_allclose(t, t_true, atol=1e-10)
    # noisy: same rotation as scipy's align_vectors on centred points (an independent solver)
    Yn = Y + rng.standard_normal(Y.shape)
    R, t = rigid_fit(X, Yn)
    rot, _ = Rotation.align_vectors(Yn - Yn.mean(0), X - X.mean(0))
    np.testing.assert_allclose(R, rot.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(t, Yn.mean(0) - R @ X.mean(0), atol=1e-10)


def test_rigid_fit_is_reflection_safe():
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) * 10
    Y = X * np.array([1, 1, -1])  # a mirror image: best proper rotation, never a reflection
    R, _ = rigid_fit(X, Y)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)


def test_align_head_noiseless_recovers_head_coordinates():
    rec, true, head = planted()
    aligned, res = align_head(rec, HEAD, reference=head)
    assert np.max(np.abs(aligned.points - true)) < 1e-9
    assert np.max(res) < 1e-9
    assert aligned.labels == rec.labels and aligned.source == rec.source


def test_align_head_default_reference_is_first_complete_frame():
    rec, true, _ = planted(F=50)
    rec.points[0, 1] = np.nan  # frame 0 lacks a head marker: frame 1 is the reference
    aligned, res = align_head(rec, HEAD)
    np.testing.assert_allclose(aligned.points[1], rec.points[1], atol=1e-9)
    # frame 0 is fitted on its 3 present head markers; ForeHead_L stays NaN there
    assert np.isnan(aligned.points[0, 1]).all()
    assert res.max() < 1e-9
    # every frame maps onto frame 1's pose by the same rigid motion of the truth
    R, t = rigid_fit(true[1], rec.points[1])
    np.testing.assert_allclose(aligned.points[2:], true[2:] @ R.T + t, atol=1e-9)


def test_align_head_noise_gives_error_of_noise_order():
    rec, true, head = planted(F=400, noise=0.5, seed=5)
    aligned, res = align_head(rec, HEAD, reference=head)
    err = np.linalg.norm(aligned.points[:, 4:] - true[:, 4:], axis=2)
    # 4 head markers with 0.5 mm noise per axis: a few tenths of a mm to ~1 mm
    assert 0.2 < np.sqrt(np.mean(err ** 2)) < 2.0
    # residual: RMS of 3-D noise, reduced by the 6 fitted degrees of freedom
    expected = 0.5 * np.sqrt(3 * (4 - 2) / 4)
    assert np.mean(res) == pytest.approx(expected, rel=0.15)


def test_align_head_keeps_fill_mask_and_nan():
    rec, _, head = planted(F=20)
    rec.filled[3, 5] = True
    rec.points[4, 6] = np.nan
    aligned, _ = align_head(rec, HEAD, reference=head)
    assert aligned.filled[3, 5] and aligned.filled.sum() == 1
    assert np.isnan(aligned.points[4, 6]).all()
    assert np.isfinite(np.delete(aligned.points[4], 6, axis=0)).all()


def test_errors():
    rec, _, head = planted(F=20)
    with pytest.raises(InputError, match=r"planted\.c3d.*'Nasion'"):
        align_head(rec, HEAD[:3] + ["Nasion"])
    with pytest.raises(InputError, match=r"planted\.c3d.*2 head marker.*at least 3"):
        align_head(rec, HEAD[:2])
    bad = Recording(rec.labels, rec.points.copy(), rec.rate, rec.source)
    bad.points[7, :2] = np.nan
    with pytest.raises(InputError, match=r"planted\.c3d: frame 7 .*ForeHead_M, ForeHead_L"):
        align_head(bad, HEAD, reference=head)
    line = rec.points.copy()
    direction = np.array([1.0, 2.0, 0.5])
    for k in range(4):
        line[:, k] = line[:, 0] + k * 10 * direction  # head markers on one line
    with pytest.raises(InputError, match="collinear"):
        align_head(Recording(rec.labels, line, rec.rate, rec.source), HEAD)
    with pytest.raises(InputError, match="collinear"):
        align_head(rec, HEAD, reference=np.outer(np.arange(4), direction))


def test_align_head_fits_each_frame_with_the_head_markers_it_has():
    """Frames lacking different head markers (every pattern with >= 3 of 4) are each fitted
    on the markers they have: the planted head coordinates come back, and each frame's
    motion equals rigid_fit on its own present markers."""
    rec, true, head = planted(F=60, noise=0.5, seed=2)
    rng = np.random.default_rng(5)
    lacking = rng.integers(-1, 4, size=60)  # -1: all four present
    for f, j in enumerate(lacking):
        if j >= 0:
            rec.points[f, j] = np.nan
    aligned, _ = align_head(rec, HEAD, reference=head)
    assert len(set(lacking.tolist())) == 5
    for f, j in enumerate(lacking):
        cols = [c for c in range(4) if c != j]
        R, t = rigid_fit(rec.points[f, cols], head[cols])
        np.testing.assert_allclose(aligned.points[f, 4:], rec.points[f, 4:] @ R.T + t,
                                   atol=1e-9)


def test_collinear_frames_match_the_svd_decision():
    """The bound that spares most frames the SVD finds exactly the frames the SVD finds:
    general, near the threshold s2 / s1 = COLLINEAR_TOL on both sides, exactly collinear,
    coincident, 3 and 6 points, far from the origin."""
    from facemotion.ingest.head_motion import COLLINEAR_TOL, _collinear_frames

    rng = np.random.default_rng(7)
    frames = []
    for m in (3, 4, 6):
        for ratio in (1.0, 0.3, 0.01, 2 * COLLINEAR_TOL, 1.01 * COLLINEAR_TOL,
                      COLLINEAR_TOL, 0.99 * COLLINEAR_TOL, 0.5 * COLLINEAR_TOL, 1e-9, 0.0):
            for _ in range(20):
                # points with singular values about (1, ratio, ratio / 3), rotated, shifted
                P = rng.standard_normal((m, 3))
                P -= P.mean(axis=0)
                U, _, Vt = np.linalg.svd(P, full_matrices=False)
                S = np.array([1.0, ratio, ratio / 3])[:len(Vt)]
                P = (U * S) @ Vt
                frames.append(P @ Rotation.random(random_state=rng).as_matrix().T
                              + rng.uniform(-500, 500, 3))
        frames.append(np.zeros((m, 3)) + 7.0)  # all points at one place
    for m in (3, 4, 6):
        X = np.stack([f for f in frames if f.shape[0] == m])
        s = np.linalg.svd(X - X.mean(axis=1, keepdims=True), compute_uv=False)
        expected = np.flatnonzero(s[:, 1] < COLLINEAR_TOL * s[:, 0])
        assert 0 < expected.size < len(X)
        np.testing.assert_array_equal(_collinear_frames(X), expected)
