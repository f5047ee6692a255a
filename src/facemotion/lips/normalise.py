"""Putting tracked lip points into the lip model's coordinates before fitting.

The paper's route (Basu & Pentland 1997, Sec. 3), exactly as printed:

1. subtract the nose point from every point (translation);
2. fit a plane to the outer subset of the upper-lip points and one to the outer subset of the
   lower-lip points (we count both mouth corners in both subsets: a corner lies on both lips);
3. the intersection line of the two planes is the x axis (oriented along global +x);
4. y = the global y axis minus its projection onto x, normalised;
5. z = x cross y.

Steps 1-5 are done in every frame (`normalise_paper`). A rotation about the new x axis (head
pitch) is left in the data by this construction, because y comes from the global y axis.
Then, once for the whole recording, the default model is fitted to the first frame by one rigid
rotation, translation and independent x, y, z scaling (`fit_scaled_rigid`), and the inverse of
that transform brings every frame into the model's coordinates (`to_model`).

`align_rigid` is an alternative for data with rigid head landmarks (a rigid, Kabsch fit of
reference landmarks to a target frame); it is a small private version of the project's head
alignment (`facemotion.ingest.head_motion`), kept here so the lip model does not depend on its API.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

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


def plane_normal(p: np.ndarray) -> np.ndarray:
    """Unit normal of the least-squares plane through points p (n, 3), n >= 3."""
    return np.linalg.svd(p - p.mean(axis=0))[2][-1]


GLOBAL_Y = np.array([0.0, 1.0, 0.0])
GLOBAL_X = np.array([1.0, 0.0, 0.0])


def lip_frame(p: np.ndarray, upper_outer: np.ndarray, lower_outer: np.ndarray,
              where: str = "frame") -> np.ndarray:
    """Rows x, y, z of the paper's lip frame (Sec. 3) for one frame's points p (M, 3)."""
    n_up, n_lo = plane_normal(p[upper_outer]), plane_normal(p[lower_outer])
    x = np.cross(n_up, n_lo)                 # direction of the planes' intersection line
    norm = np.linalg.norm(x)
    if norm < 1e-6:
        raise InputError(f"{where}: the upper- and lower-lip planes are parallel; their "
                         f"intersection (the lip x axis) is undefined")
    x = x / norm
    if x @ GLOBAL_X < 0:                     # orientation: along global +x
        x = -x
    y = GLOBAL_Y - (GLOBAL_Y @ x) * x        # global y minus its projection onto x
    if np.linalg.norm(y) < 1e-6:
        raise InputError(f"{where}: the lip x axis is vertical; the paper's y axis is undefined")
    y = y / np.linalg.norm(y)
    return np.vstack([x, y, np.cross(x, y)])  # z = x cross y


def normalise_paper(points: np.ndarray, nose: int, upper_outer: np.ndarray,
                    lower_outer: np.ndarray, source: str = "recording"
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Points (F, M, 3) in the paper's per-frame lip frame (Sec. 3) with the nose as origin.

    upper_outer / lower_outer: column indices of the outer upper-lip and outer lower-lip points
    (>= 3 each). Returns the normalised points and the frames' rotations (F, 3, 3) (rows x, y, z).
    """
    points = np.asarray(points, dtype=float)
    upper_outer = np.asarray(upper_outer, dtype=int)
    lower_outer = np.asarray(lower_outer, dtype=int)
    for name, g in (("upper", upper_outer), ("lower", lower_outer)):
        if len(g) < 3:
            raise InputError(f"{source}: the {name}-lip plane needs >= 3 outer tracked points, "
                             f"got {len(g)}")
    used = np.concatenate([[nose], upper_outer, lower_outer])
    if not np.all(np.isfinite(points[:, used])):
        f = int(np.argwhere(~np.isfinite(points[:, used]))[0][0])
        raise InputError(f"{source}: a nose or outer lip point is missing in frame {f}")
    rel = points - points[:, nose:nose + 1, :]                      # nose subtracted
    rot = np.stack([lip_frame(rel[f], upper_outer, lower_outer, f"{source}: frame {f}")
                    for f in range(len(points))])
    return np.einsum("fij,fmj->fmi", rot, rel), rot


def fit_scaled_rigid(model: np.ndarray, data: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R, s, t minimising sum |R diag(s) m_i + t - d_i|^2: the paper's one global rotation,
    translation and independent x, y, z scaling that fits the model to the first frame (Sec. 3).

    model, data: (n, 3), n >= 4 points not all in one plane. Start: Kabsch on the centred
    points with per-axis RMS scales, then scipy least_squares on (rotation vector, log s, t).
    """
    model, data = np.asarray(model, dtype=float), np.asarray(data, dtype=float)
    if model.shape != data.shape or model.ndim != 2 or model.shape[1] != 3 or len(model) < 4:
        raise InputError(f"lip model placement: need matching (n >= 4, 3) point sets, got "
                         f"{model.shape} and {data.shape}")
    mc = model - model.mean(axis=0)
    if np.any(mc.std(axis=0) <= 1e-12):
        raise InputError("lip model placement: the model's tracked nodes span fewer than "
                         "3 dimensions; per-axis scales are undefined")
    R0, _ = kabsch(mc, data - data.mean(axis=0))
    q = (data - data.mean(axis=0)) @ R0
    s0 = np.sqrt((q ** 2).sum(axis=0) / (mc ** 2).sum(axis=0))
    t0 = data.mean(axis=0) - R0 @ (s0 * model.mean(axis=0))

    def resid(par):
        R = Rotation.from_rotvec(par[:3]).as_matrix()
        return ((model * np.exp(par[3:6])) @ R.T + par[6:] - data).ravel()

    par0 = np.concatenate([Rotation.from_matrix(R0).as_rotvec(), np.log(s0), t0])
    sol = least_squares(resid, par0, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    return Rotation.from_rotvec(sol.x[:3]).as_matrix(), np.exp(sol.x[3:6]), sol.x[6:]


def to_model(points: np.ndarray, R: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The inverse of d = R diag(s) m + t applied to points (..., 3): m = diag(s)^-1 R^T (d - t)."""
    return ((np.asarray(points, dtype=float) - t) @ R) / s
