"""Putting tracked lip points into a lip frame before fitting.

Two routes:

* `normalise_paper` (Basu & Pentland 1997, section 4, as we read it): subtract the nose point,
  then rotate into a lip frame built in every frame from planes fitted to the upper-lip and
  lower-lip points. Our construction: z = the bisector of the two planes' unit normals (each
  pointing forward), x = the mouth-corner direction made orthogonal to z, y = z x x. The frame
  follows the lips, so part of any lip rotation (e.g. lower-lip eversion tilting its plane) is
  absorbed into the frame; the paper accepted this for lack of head markers.
* `align_rigid`: remove head motion by a rigid (Kabsch) fit of reference landmarks that barely
  deform to their positions in a target frame (used for the GRID data, whose nose bridge, forehead
  and eye corners are tracked). This is a small private version of the project's head alignment
  (`facemotion.head_motion`), kept here so the lip model does not depend on its API.
"""

from __future__ import annotations

import numpy as np

from facemotion.errors import InputError


def kabsch(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising sum |R a_i + t - b_i|^2 (a, b: (n, 3))."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return R, cb - R @ ca


def align_rigid(points: np.ndarray, reference: np.ndarray, target_frame: int = 0,
                source: str = "recording") -> tuple[np.ndarray, np.ndarray]:
    """Points (F, M, 3) moved so the `reference` markers best match their target-frame pose.

    Returns the aligned points and the RMS residual (mm) of the reference markers per frame.
    """
    points = np.asarray(points, dtype=float)
    ref = np.asarray(reference, dtype=int)
    if len(ref) < 3:
        raise InputError(f"{source}: rigid head alignment needs >= 3 reference markers, "
                         f"got {len(ref)}")
    target = points[target_frame, ref]
    if not np.all(np.isfinite(target)):
        raise InputError(f"{source}: a reference marker is missing in frame {target_frame}")
    out = np.empty_like(points)
    rms = np.empty(len(points))
    for f in range(len(points)):
        a = points[f, ref]
        ok = np.isfinite(a).all(axis=1)
        if ok.sum() < 3:
            raise InputError(f"{source}: fewer than 3 reference markers present in frame {f}")
        R, t = kabsch(a[ok], target[ok])
        out[f] = points[f] @ R.T + t
        rms[f] = np.sqrt(np.mean(np.sum((out[f, ref[ok]] - target[ok]) ** 2, axis=1)))
    return out, rms


def _plane_normal(p: np.ndarray) -> np.ndarray:
    """Unit normal of the least-squares plane through points p (n, 3), n >= 3."""
    return np.linalg.svd(p - p.mean(axis=0))[2][-1]


def lip_frames(points: np.ndarray, nose: int, upper: np.ndarray, lower: np.ndarray,
               corners: tuple[int, int]) -> np.ndarray:
    """Rotation (F, 3, 3) whose rows are the lip frame's x, y, z axes in every frame.

    `corners` = (a, b): x points from corner a towards corner b. Plane normals are oriented
    towards x cross (nose - mouth centre), i.e. forward for a nose above the mouth.
    """
    F = len(points)
    rot = np.empty((F, 3, 3))
    for f in range(F):
        p = points[f]
        xdir = p[corners[1]] - p[corners[0]]
        centre = 0.5 * (p[corners[0]] + p[corners[1]])
        forward = np.cross(xdir, p[nose] - centre)
        normals = []
        for group in (upper, lower):
            n = _plane_normal(p[group])
            normals.append(n if n @ forward >= 0 else -n)
        z = normals[0] + normals[1]
        z /= np.linalg.norm(z)
        x = xdir - (xdir @ z) * z
        x /= np.linalg.norm(x)
        rot[f] = np.vstack([x, np.cross(z, x), z])
    return rot


def normalise_paper(points: np.ndarray, nose: int, upper: np.ndarray, lower: np.ndarray,
                    corners: tuple[int, int], source: str = "recording") -> np.ndarray:
    """Points (F, M, 3) in the per-frame lip frame with the nose point as origin."""
    points = np.asarray(points, dtype=float)
    upper, lower = np.asarray(upper, dtype=int), np.asarray(lower, dtype=int)
    for name, g in (("upper", upper), ("lower", lower)):
        if len(g) < 3:
            raise InputError(f"{source}: the {name}-lip plane needs >= 3 tracked points, "
                             f"got {len(g)}")
    used = np.concatenate([[nose], upper, lower, list(corners)])
    if not np.all(np.isfinite(points[:, used])):
        f = int(np.argwhere(~np.isfinite(points[:, used]))[0][0])
        raise InputError(f"{source}: a nose or lip point is missing in frame {f}")
    rot = lip_frames(points, nose, upper, lower, corners)
    rel = points - points[:, nose:nose + 1, :]
    return np.einsum("fij,fmj->fmi", rot, rel)
