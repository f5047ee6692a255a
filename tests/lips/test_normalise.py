"""The paper's normalisation (Basu & Pentland 1997, Sec. 3) on planted rigid transforms."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.lips.normalise import fit_scaled_rigid, lip_frame, normalise_paper, to_model

# A lip configuration whose outer upper-lip points lie on a plane through the x axis tilted
# forward and whose outer lower-lip points lie on another such plane: the planes intersect
# exactly along the x axis. Columns: 0 nose, 1-2 corners, 3-5 upper, 6-8 lower, 9-10 inner.
A_UP, A_LO = np.radians(20), np.radians(35)
UP_DIR = np.array([0, np.cos(A_UP), np.sin(A_UP)])
LO_DIR = np.array([0, -np.cos(A_LO), np.sin(A_LO)])
BASE = np.vstack([
    [0.0, 28.0, 18.0],
    [-25, 0, 0], [25, 0, 0],
    *[np.array([x, 0, 0]) + r * UP_DIR for x, r in ((-15, 9.0), (0, 11.0), (15, 8.0))],
    *[np.array([x, 0, 0]) + r * LO_DIR for x, r in ((-14, 10.0), (0, 12.0), (16, 9.0))],
    [-10, 1, 3], [12, -2, 4],
])
UPPER, LOWER = [1, 2, 3, 4, 5], [1, 2, 6, 7, 8]


def _moved(Q, t):
    return (BASE @ Q.T + t)[None]


@pytest.mark.parametrize("yaw,roll", [(0, 0), (25, 0), (0, -15), (-30, 12)])
def test_yaw_and_roll_are_recovered_exactly(yaw, roll):
    # head tilted about the global z axis, then turned about the global y axis (Q = Ry Rz),
    # and translated: the printed construction gives back the lips in their own frame, nose
    # at the origin (x' = Q e_x, and e_y minus its projection onto x' is parallel to Q e_y)
    Q = Rotation.from_euler("zy", [roll, yaw], degrees=True).as_matrix()
    out, rot = normalise_paper(_moved(Q, [3.0, -40.0, 7.0]), 0, UPPER, LOWER)
    np.testing.assert_allclose(out[0], BASE - BASE[0], atol=1e-10)
    np.testing.assert_allclose(rot[0] @ Q, np.eye(3), atol=1e-12)


def test_pitch_is_left_in_by_the_printed_construction():
    # a rotation about the lip x axis leaves x and the global y unchanged, so the lip frame
    # does not follow it: the normalised points are the pitched points
    Q = Rotation.from_euler("x", 10, degrees=True).as_matrix()
    out, _ = normalise_paper(_moved(Q, [0, 0, 0]), 0, UPPER, LOWER)
    np.testing.assert_allclose(out[0], (BASE - BASE[0]) @ Q.T, atol=1e-10)


def test_axes_follow_the_printed_definition_for_any_rotation():
    # independent reference: x = the image of the planes' intersection (the base x axis),
    # y = global y minus its projection onto x, z = x cross y
    rng = np.random.default_rng(3)
    for Q in Rotation.random(5, random_state=rng).as_matrix():
        if abs((Q @ [1, 0, 0])[1]) > 0.9:
            continue
        x = Q @ [1.0, 0, 0]
        x = x if x[0] >= 0 else -x
        y = np.array([0, 1.0, 0]) - x[1] * x
        y /= np.linalg.norm(y)
        expected = np.vstack([x, y, np.cross(x, y)])
        pts = BASE @ Q.T
        np.testing.assert_allclose(lip_frame(pts - pts[0], UPPER, LOWER), expected, atol=1e-10)


def test_parallel_lip_planes_are_named():
    flat = BASE.copy()
    flat[3:9, 2] = 0.0                 # both lips in the plane z = 0
    with pytest.raises(InputError, match="frame 0: the upper- and lower-lip planes are parallel"):
        normalise_paper(flat[None], 0, UPPER, LOWER)


def test_scaled_rigid_fit_recovers_a_planted_transform():
    rng = np.random.default_rng(7)
    model = rng.normal(size=(16, 3)) * [25, 12, 8]
    R = Rotation.from_rotvec([0.2, -0.4, 0.3]).as_matrix()
    s, t = np.array([0.8, 1.3, 2.1]), np.array([5.0, -2.0, 30.0])
    data = (model * s) @ R.T + t
    R_hat, s_hat, t_hat = fit_scaled_rigid(model, data)
    np.testing.assert_allclose(R_hat, R, atol=1e-9)
    np.testing.assert_allclose(s_hat, s, rtol=1e-9)
    np.testing.assert_allclose(t_hat, t, atol=1e-8)
    np.testing.assert_allclose(to_model(data, R_hat, s_hat, t_hat), model, atol=1e-8)
