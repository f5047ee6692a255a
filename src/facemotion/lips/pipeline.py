"""Stage functions of the lip-model study (Basu & Pentland 1997); workflow scripts call these.

`run_lip_model` is the whole analysis of one recording on one mesh, in the paper's order:

1. normalise the tracked points ('paper', Sec. 3: nose subtracted, lip frame from planes through
   the outer upper- and outer lower-lip points, in every frame; 'rigid': head motion removed by a
   rigid fit of head landmarks; 'none');
2. bring the data into the model's coordinates: one rigid rotation, translation and independent
   x, y, z scaling fits the default model's tracked nodes to the first frame, and its inverse is
   applied to every frame (Sec. 3);
3. deform the default model to the first frame with least force (the "rest state", Sec. 2.4 and
   Fig. 7) and re-assemble K there; the goals U_g of every frame are then the data points minus
   the rest-state nodes (Sec. 4);
4. minimal-force fit of every frame (eqs. 7-10);
5. express the displacements in model units: the default model's bounding box is scaled to the
   paper's 2.35 x 2.83 x 5.05 units (x, y, z; `mesh.PAPER_MODEL_EXTENT`), so the modes and
   Table 1 are in the paper's units. The FEM itself works on the mesh in mm: the units only
   rescale the coordinates, they do not reshape the physics;
6. PCA of the training frames' displacements over all free DOF (sample covariance eq. 13);
7. LLSE of the test frames' whole shape from partial views (Sec. 5, Table 1): xyz of 8 points,
   yz of all points (profile), xy of all points (frontal). 'All points' are the tracked points
   (the paper's reading, `point_set` 'tracked_points'); the lip-band mesh nodes are an option
   ('mesh_nodes'). Estimators: the n-mode covariance and the full sample covariance, each
   under two readings of the paper's LLSE (column `estimator_reading`): 'noise_term'
   (sigma^2 from probabilistic PCA, `noise` 'regularised'; the chosen reading, below) and
   'pseudo_inverse' (sigma^2 = 0, `noise` 'noise_free'). Error: mean squared error per DOF over
   all free DOF of the model and over the test frames, against the minimal-force fits of the
   test frames (the paper's reference), in model units^2 and in mm^2.

The chosen estimator reading (`CHOSEN_READING`, column `chosen_reading`). B&P print the LLSE
without a noise term and observe "any subset of the displacements" (Sec. 4.2). The formula
m + Lambda H^T (H Lambda H^T)^-1 (y - H m) needs H Lambda H^T invertible. For the full sample
covariance it is (rank up to 139 from 140 frames, 24 or 32 observed DOF), and the formula is
used as printed. For the 10-mode covariance Phi diag(lambda) Phi^T (Sec. 4.2, "reassemble the
sample covariance matrix as S Lambda S^T" from 10 eigenvectors) it is not: H Lambda H^T has rank
10 and 24 or 32 rows, so the printed inverse does not exist and the paper's Table 1 column
needs a reading. Two fill the gap: the pseudo-inverse (the sigma^2 -> 0 limit, least squares on
the 10 modes) and a noise term sigma^2 I. We choose the noise term, with sigma^2 the
probabilistic-PCA variance (`llse.ppca_noise_var`), because the paper itself gives the variance
outside the 10 modes the role of noise ("noise in the observations makes it unreasonable to
estimate even this many modes", Sec. 4.2), and its Sec. 4.1 argument (the LLSE is the maximum
of a Gaussian likelihood, eqs. 11-12) needs a Gaussian whose covariance is of full rank on the
observed DOF: the rank-10 Gaussian gives observed data outside its 10-dimensional support zero
density, while the 10 modes plus the left-out variance spread over the other directions is the
Gaussian the truncation describes, with no free parameter. The same observation noise is applied
to both columns (it is a property of the observations, not of the prior). The pseudo-inverse
reading is reported beside it in every table.

`virtual_lip_study` and `grid_lip_study` wrap it for the virtual talker and the GRID clips;
`lip_study` runs one lip subject of the workflow's settings (`LipSettings`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.io.recording import Recording
from facemotion.lips.fem import assemble_stiffness
from facemotion.lips.fitting import MinimalForceFitter, fit_residuals
from facemotion.lips.llse import LLSE, ppca_noise_var
from facemotion.lips.mesh import PAPER_MODEL_EXTENT, LipMesh, canonical_lip_mesh, model_units_per_mm
from facemotion.lips.normalise import align_rigid, fit_scaled_rigid, normalise_paper, to_model
from facemotion.lips.pca import Modes, pca_svd
from facemotion.lips.virtual import VirtualLipTalker, depth_share, make_virtual_talker

log = logging.getLogger("facemotion")

VIEWS = ("xyz_8_points", "yz_all_points", "xy_all_points")
VIEW_AXES = {"xyz_8_points": (0, 1, 2), "yz_all_points": (1, 2), "xy_all_points": (0, 1)}
POINT_SETS = ("tracked_points", "mesh_nodes")
NOISES = ("noise_free", "regularised")
# the two readings of the paper's LLSE (module docstring): noise setting -> reading
ESTIMATOR_READINGS = {"noise_free": "pseudo_inverse", "regularised": "noise_term"}
CHOSEN_READING = "noise_term"
NOISE_GRID = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2)

# Basu & Pentland (1997), Table 1: reconstruction error per DOF in the model's normalised units,
# (first 10 modes, full covariance).
PAPER_TABLE1 = {"xyz_8_points": (1.10e-3, 7.80e-4), "yz_all_points": (7.13e-4, 4.38e-4),
                "xy_all_points": (6.70e-3, 7.50e-3)}
PAPER_COUNTS = {  # quantity: (paper value, unit, place in the paper)
    "triangles": (336, "count", "Sec. 2.1"),
    "nodes": (204, "count", "Sec. 2.1"),
    "dof": (612, "count", "Sec. 2.1"),
    "free_dof": (600, "count", "Sec. 4.1 (P has 600 columns: 4 nodes grounded; Sec. 2.3 says "
                               "2 nodes, 6 DOF: the paper is inconsistent)"),
    "open_dof": (564, "count", "Sec. 4.1 (DOF left open: 612 - 48, the grounded ones "
                               "counted as open)"),
    "open_free_dof": (np.nan, "count", "not printed: free DOF less the constrained ones"),
    "tracked_lip_points": (16, "count", "Sec. 3"),
    "nose_points": (1, "count", "Sec. 3"),
    "constrained_dof": (48, "count", "Sec. 4.1"),
    "frames": (150, "count", "Sec. 3"),
    "frame_rate_hz": (30.0, "Hz", "Sec. 3"),
    "training_frames": (140, "count", "Sec. 5"),
    "test_frames": (10, "count", "Sec. 5"),
    "modes": (10, "count", "Sec. 4.2, 5"),
    "variance_in_modes_percent": (99.2, "%", "Sec. 5"),
    "model_extent_x": (2.35, "model units", "Sec. 5"),
    "model_extent_y": (2.83, "model units", "Sec. 5"),
    "model_extent_z": (5.05, "model units", "Sec. 5"),
    "poisson_ratio": (0.01, "1", "Sec. 2.3"),
    "youngs_modulus": (1.0, "1", "Sec. 2.3"),
    "ridge_stiffness_factor": (2.0, "1", "Sec. 2.4"),
}

# GRID talker: 16 tracked lip landmarks of the canonical mesh (outer contour first: its 8 points
# are the 8-point view), the nose tip (canonical vertex 1), and the reference landmarks for a
# rigid head fit (data README).
GRID_TRACKED = ["L061", "L291", "L000", "L017", "L040", "L270", "L091", "L321",
                "L078", "L308", "L013", "L014", "L081", "L311", "L178", "L402"]
GRID_NOSE = "L001"
GRID_REFERENCE = ["L006", "L168", "L197", "L195", "L010", "L151", "L009",
                  "L033", "L133", "L263", "L362"]


@dataclass
class LipModelResult:
    """Everything `run_lip_model` measured.

    Tables: `modes` (mode, variance in model units^2, cumulative_fraction), `fit_residuals`
    (frame, max/rms residual mm), `reconstruction` (Table 1, long: one row per view x point set
    x covariance x noise; see `reconstruction_table`), `noise_sensitivity`, `counts` (ours
    beside the paper's), `heldout_landmarks` (GRID: view, landmark, rms_error_mm) and
    `truth_recovery` (virtual: per-frame error of the fit against the planted truth).
    Arrays: `displacements` (frames, N, 3) fitted, mm; `mean_displacement` (N, 3) and
    `mode_shapes` (k, N, 3) in model units (unit-norm modes, zero on fixed nodes); `mode_sd`
    (k,) model units. `mesh` is the rest-state mesh in the model's mm coordinates;
    `model_units_per_mm` (3,) model units per mm along x, y, z.
    """

    mesh: LipMesh
    tracked: list[str]
    displacements: np.ndarray
    goals: np.ndarray
    mean_displacement: np.ndarray
    mode_shapes: np.ndarray
    mode_sd: np.ndarray
    mode_variance_fraction: np.ndarray
    model_units_per_mm: np.ndarray
    noise_var: float
    noise_var_choice: str
    train_frames: np.ndarray
    test_frames: np.ndarray
    placement: dict
    modes: pd.DataFrame
    fit_residuals: pd.DataFrame
    reconstruction: pd.DataFrame
    noise_sensitivity: pd.DataFrame
    counts: pd.DataFrame
    heldout_landmarks: pd.DataFrame | None = None
    truth_recovery: pd.DataFrame | None = None


def _frames(frames, n: int, default: np.ndarray, name: str) -> np.ndarray:
    f = default if frames is None else np.asarray(list(frames), dtype=int)
    if f.ndim != 1 or len(f) == 0:
        raise InputError(f"{name}: no frames selected")
    if f.min() < 0 or f.max() >= n:
        raise InputError(f"{name}: frames must be in 0..{n - 1} "
                         f"(0-based), got {f.min()}..{f.max()}")
    return f


def view_nodes(mesh: LipMesh, view: str, point_set: str, tracked: list[str],
               view_points: list[str]) -> tuple[np.ndarray, tuple[int, ...]]:
    """Node indices and axes (0 x, 1 y, 2 z) a view observes.

    xyz_8_points: the 8 view points, x, y, z. yz_all_points / xy_all_points: every tracked
    point ('tracked_points', the paper's reading) or every lip-band node ('mesh_nodes').
    """
    if view not in VIEW_AXES:
        raise InputError(f"view: unknown view {view!r} (allowed {VIEWS})")
    if point_set not in POINT_SETS:
        raise InputError(f"point_set: unknown point set {point_set!r} (allowed {POINT_SETS})")
    if view == "xyz_8_points":
        nodes = mesh.indices(view_points)
    elif point_set == "tracked_points":
        nodes = mesh.indices(tracked)
    else:
        nodes = mesh.band_nodes
    return nodes, VIEW_AXES[view]


def state_positions(mesh: LipMesh, state_dofs: np.ndarray, nodes: np.ndarray,
                    axes) -> np.ndarray:
    """Positions in the state vector (the free DOF, `state_dofs`) of the given nodes' axes."""
    where = -np.ones(3 * mesh.n_nodes, dtype=int)
    where[state_dofs] = np.arange(len(state_dofs))
    pos = where[(3 * np.asarray(nodes)[:, None] + np.asarray(axes)).ravel()]
    if np.any(pos < 0):
        raise InputError(f"{mesh.name}: a view observes a fixed node")
    return pos


def outer_subsets(mesh: LipMesh, tracked: list[str]) -> tuple[list[str], list[str]]:
    """The outer subsets of the upper- and lower-lip tracked points (both mouth corners in each)."""
    tr = mesh.indices(tracked)
    outer = mesh.role[tr] == "outer"
    part = mesh.part[tr]
    rows = list(zip(tracked, outer, part, strict=True))
    upper = [t for t, o, p in rows if o and p in ("upper", "corner")]
    lower = [t for t, o, p in rows if o and p in ("lower", "corner")]
    return upper, lower


def normalise_recording(recording: Recording, normalisation: str, upper_outer: list[str],
                        lower_outer: list[str], nose_label: str | None,
                        reference_labels: list[str] | None) -> np.ndarray:
    """The recording's points (F, M, 3) normalised: 'paper', 'rigid' or 'none'."""
    pts = recording.points
    if normalisation == "paper":
        if nose_label is None:
            raise InputError("nose_label: the paper's normalisation needs "
                             "a nose point")
        return normalise_paper(pts, recording.index(nose_label),
                               [recording.index(t) for t in upper_outer],
                               [recording.index(t) for t in lower_outer],
                               source=recording.source)[0]
    if normalisation == "rigid":
        if not reference_labels:
            raise InputError("reference_labels: rigid head alignment needs "
                             "reference landmarks")
        ref = [recording.index(r) for r in reference_labels]
        return align_rigid(pts, np.array(ref), source=recording.source)[0]
    if normalisation == "none":
        return np.asarray(pts, dtype=float)
    raise InputError(f"normalisation: {normalisation!r} is not one of "
                     f"'paper', 'rigid', 'none'")


def _mse_per_dof(est: np.ndarray, ref: np.ndarray, scale: np.ndarray | None = None) -> float:
    d = est - ref
    if scale is not None:
        d = d / scale
    return float(np.mean(d ** 2))


def run_lip_model(mesh: LipMesh, recording: Recording, tracked_labels: list[str], *,
                  normalisation: str = "paper", nose_label: str | None = None,
                  reference_labels: list[str] | None = None, train_frames=None,
                  test_frames=None, n_modes: int = 10, noise_var: float | str = "ppca",
                  view_points: list[str] | None = None,
                  heldout_labels: list[str] | None = None, truth: np.ndarray | None = None,
                  model_extent=PAPER_MODEL_EXTENT, E: float = 1.0, nu: float = 0.01,
                  ridge_factor: float = 2.0, strip_factor: float = 0.5,
                  noise_grid: tuple[float, ...] = NOISE_GRID) -> LipModelResult:
    """Fit, learn modes and reconstruct from views; see the module docstring.

    Frames are 0-based; defaults: train on all but the last 10 frames, test on the last 10
    (the paper: 1-140 and 141-150 of 150). noise_var: model units^2, or 'ppca' (the variance
    the n modes leave out, per remaining DOF; `llse.ppca_noise_var`) for the regularised
    estimators. model_extent: (x, y, z) size of the default model in model units (the paper's
    2.35, 2.83, 5.05), or None for mm. view_points: the 8-point view (default: the first 8
    tracked). truth: planted displacements (frames, N, 3) in the mesh's own frame, mm.
    """
    tracked = [str(t) for t in tracked_labels]
    if len(tracked) != len(set(tracked)):
        raise InputError(f"tracked_labels: repeated labels in {tracked}")
    F = recording.n_frames
    train, test = split_frames(train_frames, test_frames, F)
    physics = {"E": E, "nu": nu, "ridge_factor": ridge_factor, "strip_factor": strip_factor}
    data_m, R, s = model_coordinates(mesh, recording, tracked, normalisation, nose_label,
                                     reference_labels)                          # steps 1-2
    cols = [recording.index(t) for t in tracked]
    fit = fit_frames(mesh, data_m[:, cols], tracked, physics)                    # steps 3-4
    k_unit = model_units_per_mm(mesh, model_extent)                          # step 5
    data = (fit.displacements * k_unit).reshape(F, -1)[:, fit.state]
    learned = learn_modes(data[train], n_modes, noise_var)                       # step 6
    truth_state = None
    if truth is not None:
        truth = np.asarray(truth, dtype=float)
        if truth.shape != (F, mesh.n_nodes, 3):
            raise InputError(f"lip model: truth must be ({F}, {mesh.n_nodes}, 3), got "
                             f"{truth.shape}")
        truth_state = (truth * k_unit).reshape(F, -1)[:, fit.state]
    view_points = list(view_points) if view_points is not None else tracked[:8]
    obs = observed_positions(fit.rest, fit.state, tracked, view_points)
    unit_of_state = k_unit[fit.state % 3]
    recon = reconstruction_table(reconstruction_rows(                             # step 7
        obs, learned, data, test, unit_of_state,
        None if truth_state is None else truth_state[test]), n_modes)
    heldout = None
    if heldout_labels:
        heldout = _heldout_table(fit.rest, recording, data_m, tracked, heldout_labels,
                                 fit.displacements, learned.estimators[f"{n_modes}_modes"],
                                 fit.state, k_unit, obs, learned.noise_var, test)
    counts = counts_table(mesh, tracked, nose_label is not None,
                          F, recording.rate, train, test, n_modes,
                          float(learned.variance_fraction.sum()), k_unit, model_extent, E, nu,
                          ridge_factor)
    return LipModelResult(
        mesh=fit.rest, tracked=tracked, displacements=fit.displacements, goals=fit.goals,
        **learned.shapes(mesh.n_nodes, fit.state),
        model_units_per_mm=k_unit, noise_var=learned.noise_var, noise_var_choice=learned.choice,
        train_frames=train, test_frames=test, placement=_placement(R, s, fit.rest_goal),
        modes=learned.all.table().head(max(n_modes, min(learned.all.n_modes, 20))),
        fit_residuals=fit.residuals, reconstruction=recon,
        noise_sensitivity=noise_sensitivity(obs, learned, data[test], noise_grid),
        counts=counts, heldout_landmarks=heldout,
        truth_recovery=None if truth_state is None else truth_recovery(data, truth_state,
                                                                       unit_of_state))


def split_frames(train_frames, test_frames, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Training and test frames (0-based), checked; defaults: the last 10 frames test."""
    test = _frames(test_frames, n, np.arange(max(n - 10, 1), n), "test_frames")
    train = _frames(train_frames, n, np.arange(0, max(n - 10, 1)), "train_frames")
    if np.intersect1d(train, test).size:
        raise InputError("train_frames, test_frames: the training and test frames overlap")
    return train, test


def model_coordinates(mesh: LipMesh, recording: Recording, tracked: list[str],
                      normalisation: str, nose_label: str | None,
                      reference_labels: list[str] | None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The recording's points normalised and brought into the model's coordinates (Sec. 3),
    with the rotation R and the x, y, z scale s of the model's fit to the first frame."""
    tracked_nodes = mesh.indices(tracked)  # names a label that is not a node
    cols = [recording.index(t) for t in tracked]
    upper, lower = outer_subsets(mesh, tracked)
    pts = normalise_recording(recording, normalisation, upper, lower, nose_label,
                              reference_labels)
    if not np.all(np.isfinite(pts[:, cols])):
        f, j = np.argwhere(~np.isfinite(pts[:, cols]).all(axis=2))[0]
        raise InputError(f"{recording.source}: tracked point {tracked[j]} is missing in "
                         f"frame {f}")
    # the default model fitted to the first frame by rotation, translation and x, y, z scaling;
    # its inverse brings the data into the model's coordinates (Sec. 3)
    R, s, t = fit_scaled_rigid(mesh.nodes[tracked_nodes], pts[0, cols])
    return to_model(pts, R, s, t), R, s


@dataclass
class LipFit:
    """The minimal-force fits: the rest-state mesh, its goal (mm) on the first frame, the
    goals U_g and displacements U of every frame (mm), the residuals, and the free DOF."""

    rest: LipMesh
    rest_goal: np.ndarray
    goals: np.ndarray
    displacements: np.ndarray
    residuals: pd.DataFrame
    state: np.ndarray


def fit_frames(mesh: LipMesh, tracked_m: np.ndarray, tracked: list[str], physics: dict
               ) -> LipFit:
    """Rest state on the first frame (Sec. 2.4, Fig. 7), then every frame's fit (eqs. 7-10);
    ``tracked_m``: the tracked points (frames, M, 3) in the model's coordinates."""
    tracked_nodes = mesh.indices(tracked)
    # rest state: the default model deformed to the first frame, physics re-linearised there
    rest_goal = tracked_m[0] - mesh.nodes[tracked_nodes]
    u_rest = MinimalForceFitter(mesh, assemble_stiffness(mesh, **physics), tracked).fit(
        rest_goal)[0]
    rest = mesh.with_nodes(mesh.nodes + u_rest)
    goals = tracked_m - rest.nodes[tracked_nodes]                       # U_g (Sec. 4)
    fitter = MinimalForceFitter(rest, assemble_stiffness(rest, **physics), tracked)
    U = fitter.fit(goals)                                               # eqs. 7-10
    return LipFit(rest, rest_goal, goals, U, fit_residuals(U, goals, fitter.tracked),
                  fitter.dofs)


def _placement(R: np.ndarray, s: np.ndarray, rest_goal: np.ndarray) -> dict:
    return {"scale_x": s[0], "scale_y": s[1], "scale_z": s[2],
            "rotation_deg": float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))),
            "rest_rms_mm": float(np.sqrt(np.mean(np.sum(rest_goal ** 2, axis=1))))}


@dataclass
class LearnedModes:
    """PCA of the training frames (``all`` modes, the first n kept), the regularised
    estimators' noise variance and its origin, and the two LLSE estimators."""

    all: Modes
    modes: Modes
    noise_var: float
    choice: str
    estimators: dict[str, LLSE]

    @property
    def variance_fraction(self) -> np.ndarray:
        """Each kept mode's share of the total variance."""
        return self.modes.variances / self.all.total_variance

    def shapes(self, n_nodes: int, state: np.ndarray) -> dict:
        """Mean and mode shapes on every node (zero on fixed nodes), model units."""
        n_modes = self.modes.modes.shape[0]
        U_modes = np.zeros((n_modes, 3 * n_nodes))
        U_modes[:, state] = self.modes.modes
        mean = np.zeros(3 * n_nodes)
        mean[state] = self.modes.mean
        return {"mean_displacement": mean.reshape(-1, 3),
                "mode_shapes": U_modes.reshape(n_modes, -1, 3),
                "mode_sd": np.sqrt(self.modes.variances),
                "mode_variance_fraction": self.variance_fraction}


def learn_modes(train_data: np.ndarray, n_modes: int, noise_var: float | str) -> LearnedModes:
    """PCA of the training frames (sample covariance, eq. 13) and the LLSE estimators."""
    all_modes = pca_svd(train_data)
    if n_modes > all_modes.n_modes:
        raise InputError(f"n_modes: {n_modes} modes requested but "
                         f"{len(train_data)} training frames support at most "
                         f"{all_modes.n_modes}")
    modes = all_modes.truncated(n_modes)
    if noise_var == "ppca":
        s2, choice = ppca_noise_var(all_modes, n_modes, train_data.shape[1]), "ppca"
    else:
        s2, choice = float(noise_var), "setting"
    estimators = {f"{n_modes}_modes": LLSE.from_modes(modes),
                  "full_covariance": LLSE.from_data(train_data)}
    return LearnedModes(all_modes, modes, s2, choice, estimators)


def observed_positions(rest: LipMesh, state: np.ndarray, tracked: list[str],
                       view_points: list[str]) -> dict[tuple[str, str], np.ndarray]:
    """Each (view, point set)'s observed positions in the state vector."""
    obs = {}
    for ps in POINT_SETS:
        for v in VIEWS:
            nodes, axes = view_nodes(rest, v, ps, tracked, view_points)
            obs[v, ps] = state_positions(rest, state, nodes, axes)
    return obs


def reconstruction_rows(obs: dict, learned: LearnedModes, data: np.ndarray, test: np.ndarray,
                        unit_of_state: np.ndarray, truth_test: np.ndarray | None = None
                        ) -> pd.DataFrame:
    """LLSE of the test frames' whole shape from each view (Sec. 5): one row per view x point
    set x covariance x noise, MSE per DOF against the minimal-force fits (and the truth)."""
    target = data[test]
    mean_shape_err = _mse_per_dof(np.broadcast_to(learned.modes.mean, target.shape), target)
    rows = []
    for (v, ps), o in obs.items():
        for cov, est in learned.estimators.items():
            for noise, s2v in (("noise_free", 0.0), ("regularised", learned.noise_var)):
                u = est.estimate(target[:, o], o, s2v)
                row = {"view": v, "point_set": ps, "covariance": cov, "noise": noise,
                       "estimator_reading": ESTIMATOR_READINGS[noise],
                       "noise_var_model_units2": s2v, "n_observed_dof": len(o),
                       "n_evaluated_dof": data.shape[1], "n_test_frames": len(test),
                       "mse_per_dof_model_units2": _mse_per_dof(u, target),
                       "mse_per_dof_mm2": _mse_per_dof(u, target, unit_of_state),
                       "mse_mean_shape_model_units2": mean_shape_err}
                if truth_test is not None:
                    row["mse_vs_truth_model_units2"] = _mse_per_dof(u, truth_test)
                rows.append(row)
    return pd.DataFrame(rows)


def noise_sensitivity(obs: dict, learned: LearnedModes, target: np.ndarray,
                      noise_grid: tuple[float, ...]) -> pd.DataFrame:
    """MSE per DOF of every view and estimator at each noise variance of the grid and at the
    one chosen."""
    sens = []
    for value, how in [(g, "grid") for g in noise_grid] + [(learned.noise_var, learned.choice)]:
        for (v, ps), o in obs.items():
            for cov, est in learned.estimators.items():
                u = est.estimate(target[:, o], o, value)
                sens.append({"noise_var_model_units2": value, "choice": how, "view": v,
                             "point_set": ps, "covariance": cov,
                             "mse_per_dof_model_units2": _mse_per_dof(u, target)})
    return pd.DataFrame(sens)


def truth_recovery(data: np.ndarray, truth_state: np.ndarray, unit_of_state: np.ndarray
                   ) -> pd.DataFrame:
    """Per frame: RMS 3-D error (mm) of the fitted displacements against the planted truth."""
    err = (data - truth_state) / unit_of_state
    tru = truth_state / unit_of_state
    return pd.DataFrame({
        "frame": np.arange(len(data)),
        "rms_error_mm": np.sqrt(np.mean(err ** 2, axis=1) * 3),
        "rms_truth_displacement_mm": np.sqrt(np.mean(tru ** 2, axis=1) * 3),
    })


def reconstruction_table(rows: pd.DataFrame, n_modes: int) -> pd.DataFrame:
    """Table 1, long: adds `chosen_reading` (the row's estimator reading is `CHOSEN_READING`),
    `paper_definition` (tracked points under the chosen reading) and, on the tracked-point rows
    of the 10-mode and full covariance under either reading, the paper's value
    `paper_mse_per_dof_model_units2` and its place."""
    rows = rows.copy()
    rows["rmse_mm"] = np.sqrt(rows["mse_per_dof_mm2"])
    rows["chosen_reading"] = rows["estimator_reading"] == CHOSEN_READING
    tracked = rows["point_set"] == "tracked_points"
    rows["paper_definition"] = tracked & rows["chosen_reading"]
    paper = []
    for on_tracked, (_, r) in zip(tracked, rows.iterrows(), strict=True):
        col = {"10_modes": 0, "full_covariance": 1}.get(r["covariance"])
        ok = on_tracked and col is not None and (
            r["covariance"] != "10_modes" or n_modes == 10)
        paper.append(PAPER_TABLE1[r["view"]][col] if ok else np.nan)
    rows["paper_mse_per_dof_model_units2"] = paper
    rows["paper_place"] = np.where(np.isfinite(paper), "Basu & Pentland 1997, Table 1", "")
    return rows


def counts_table(mesh: LipMesh, tracked: list[str], has_nose: bool, frames: int, rate: float,
                 train: np.ndarray, test: np.ndarray, n_modes: int, fraction: float,
                 k_unit: np.ndarray, model_extent, E: float, nu: float,
                 ridge_factor: float) -> pd.DataFrame:
    """The paper's model and data counts (Secs. 2-5) beside ours."""
    free = 3 * (mesh.n_nodes - len(mesh.fixed))
    constrained = 3 * len(tracked)
    ext = (k_unit * (mesh.nodes.max(axis=0) - mesh.nodes.min(axis=0)))
    ours = {"triangles": mesh.n_triangles, "nodes": mesh.n_nodes, "dof": 3 * mesh.n_nodes,
            "free_dof": free, "open_dof": 3 * mesh.n_nodes - constrained,
            "open_free_dof": free - constrained,
            "tracked_lip_points": len(tracked), "nose_points": int(has_nose),
            "constrained_dof": constrained, "frames": frames, "frame_rate_hz": rate,
            "training_frames": len(train), "test_frames": len(test), "modes": n_modes,
            "variance_in_modes_percent": 100 * fraction, "model_extent_x": ext[0],
            "model_extent_y": ext[1], "model_extent_z": ext[2], "poisson_ratio": nu,
            "youngs_modulus": E, "ridge_stiffness_factor": ridge_factor}
    unit = "model units" if model_extent is not None else "mm"
    rows = []
    for q, (pv, u, place) in PAPER_COUNTS.items():
        rows.append({"quantity": q, "paper_value": pv, "our_value": ours[q],
                     "unit": unit if u == "model units" else u, "paper_place": place})
    return pd.DataFrame(rows)


def _heldout_table(mesh: LipMesh, recording: Recording, data_m: np.ndarray,
                   tracked: list[str], heldout: list[str], U: np.ndarray, est: LLSE,
                   state: np.ndarray, k_unit: np.ndarray, obs: dict, s2: float,
                   test: np.ndarray) -> pd.DataFrame:
    """RMS 3-D error (mm, test frames) at landmarks that were not tracked.

    Measured displacement: the landmark's position in the model's coordinates minus its
    first-frame position. Predictors: the minimal-force fit from the tracked points, and the
    n-mode LLSE (noise-free and regularised) from each view of the tracked points, whose
    observations are the fitted (= measured) displacements of the tracked points.
    """
    bad = sorted(set(heldout) & set(tracked))
    if bad:
        raise InputError(f"heldout_labels: {bad} are tracked, not held out")
    h_nodes = mesh.indices(heldout)
    h_cols = [recording.index(h) for h in heldout]
    measured = data_m[:, h_cols] - data_m[0, h_cols]
    if not np.all(np.isfinite(measured[test])):
        raise InputError(f"{recording.source}: a held-out landmark is missing in a test frame")
    F = len(U)
    data = (U * k_unit).reshape(F, -1)[:, state]
    h_state = state_positions(mesh, state, h_nodes, (0, 1, 2))
    preds = {("minimal_force_fit", ""): U[test][:, h_nodes]}
    for (v, ps), o in obs.items():
        if ps != "tracked_points":
            continue
        for noise, s2v in (("noise_free", 0.0), ("regularised", s2)):
            u = est.estimate(data[test][:, o], o, s2v)[:, h_state]
            preds[v, noise] = u.reshape(len(test), len(h_nodes), 3) / k_unit
    rows = []
    disp = np.sqrt(np.mean(np.sum(measured[test] ** 2, axis=2), axis=0))
    for (v, noise), p in preds.items():
        err = np.sqrt(np.mean(np.sum((p - measured[test]) ** 2, axis=2), axis=0))
        for j, label in enumerate(heldout):
            rows.append({"view": v, "noise": noise, "landmark": label,
                         "rms_error_mm": err[j], "rms_displacement_mm": disp[j]})
    return pd.DataFrame(rows)


def virtual_lip_study(seed: int = 0, normalisation: str = "paper",
                      talker_kwargs: dict | None = None,
                      **model_kwargs) -> tuple[VirtualLipTalker, LipModelResult]:
    """The virtual talker through the model. normalisation 'paper' (nose + lip planes, the
    paper's way) or 'rigid' (rigid fit of the nose and the three head points)."""
    talker = make_virtual_talker(seed=seed, **(talker_kwargs or {}))
    return talker, run_virtual(talker, talker.recording, normalisation, **model_kwargs)


def run_virtual(talker: VirtualLipTalker, recording: Recording, normalisation: str = "paper",
                **model_kwargs) -> LipModelResult:
    """`run_lip_model` on a recording of the virtual talker (its own or read back from file)."""
    result = run_lip_model(talker.mesh, recording, talker.tracked_labels,
                           normalisation=normalisation, nose_label=talker.nose_label,
                           reference_labels=talker.head_labels,
                           view_points=talker.view_labels, truth=talker.truth, **model_kwargs)
    test = result.test_frames
    share = depth_share(talker.truth[:, talker.mesh.indices(talker.tracked_labels)], test)
    extra = pd.DataFrame([{"quantity": "depth_share_test_frames", "paper_value": np.nan,
                           "our_value": share, "unit": "1",
                           "paper_place": "Sec. 5 ('significant depth variation'); "
                                          "calibration target >= 1/3"}])
    result.counts = pd.concat([result.counts, extra], ignore_index=True)
    return result


def concatenate_recordings(recordings: list[Recording]) -> Recording:
    """One recording of several takes of the same markers, frames one after another."""
    if not recordings:
        raise InputError("lip model: no recordings given")
    first = recordings[0]
    for rec in recordings[1:]:
        if rec.labels != first.labels:
            raise InputError(f"{rec.source}: marker labels differ from {first.source}")
        if rec.rate != first.rate:
            raise InputError(f"{rec.source}: frame rate {rec.rate} Hz differs from "
                             f"{first.source} ({first.rate} Hz)")
    return Recording(first.labels, np.concatenate([r.points for r in recordings]), first.rate,
                     " + ".join(r.source for r in recordings),
                     np.concatenate([r.filled for r in recordings]))


def grid_lip_study(recordings: list[Recording], obj_path,
                   tracked_labels: list[str] = GRID_TRACKED, nose_label: str = GRID_NOSE,
                   reference_labels: list[str] = GRID_REFERENCE, normalisation: str = "paper",
                   strip_rings: int = 2, **model_kwargs) -> LipModelResult:
    """The GRID talker's clips, concatenated (2 x 75 = 150 frames; train 0-139, test 140-149
    as in the paper), on the canonical lip band whose rest geometry is the talker's own first
    frame, normalised; every untracked band landmark is held out."""
    rec = concatenate_recordings(recordings)
    topology = canonical_lip_mesh(obj_path, strip_rings=strip_rings)
    upper, lower = outer_subsets(topology, tracked_labels)
    pts = normalise_recording(rec, normalisation, upper, lower, nose_label, reference_labels)
    labels = [topology.labels[i] for i in topology.band_nodes]
    first = {lab: pts[0, rec.index(lab)] for lab in labels}
    mesh = canonical_lip_mesh(obj_path, strip_rings=strip_rings, band_nodes=first)
    heldout = [lab for lab in labels if lab not in tracked_labels]
    normalised = Recording(rec.labels, pts, rec.rate, rec.source, rec.filled)
    return run_lip_model(mesh, normalised, tracked_labels, normalisation="none",
                         nose_label=nose_label, view_points=tracked_labels[:8],
                         heldout_labels=heldout, **model_kwargs)


@dataclass(frozen=True)
class LipSettings:
    """The lip model's settings a study sets (config ``lips``), frames 0-based; the keyword
    arguments of :func:`run_lip_model` they stand for are :meth:`model_kwargs`."""

    train_frames: tuple[int, ...] | None = None
    test_frames: tuple[int, ...] | None = None
    n_modes: int = 10
    noise_var: float | str = "ppca"
    E: float = 1.0
    nu: float = 0.01
    model_extent: tuple[float, float, float] | None = PAPER_MODEL_EXTENT
    noise_grid: tuple[float, ...] = NOISE_GRID
    normalisation: str = "paper"

    def model_kwargs(self) -> dict:
        """The settings other than the normalisation, as run_lip_model's keyword arguments."""
        return {"train_frames": self.train_frames, "test_frames": self.test_frames,
                "n_modes": self.n_modes, "noise_var": self.noise_var, "E": self.E,
                "nu": self.nu, "model_extent": self.model_extent, "noise_grid": self.noise_grid}


@dataclass
class LipStudy:
    """One lip subject's study as the workflow writes it: the model's result, the talker's
    name, and its table of points not used for the fit (GRID: the held-out landmarks;
    virtual: the recovery of the planted truth)."""

    subject: str
    talker: str
    result: LipModelResult
    heldout_points: pd.DataFrame

    @property
    def modes_title(self) -> str:
        """The title of the modes figure (the paper's Fig. 9)."""
        return (f"{self.talker} ({self.subject}): mean displacement and characteristic modes "
                f"(Basu & Pentland 1997, Fig. 9)")

    @property
    def reconstruction(self) -> pd.DataFrame:
        """Table 1 (long), with the lip subject in the first column."""
        return _with_subject(self.result.reconstruction, self.subject)

    @property
    def counts(self) -> pd.DataFrame:
        """The paper's counts beside ours, with the lip subject in the first column."""
        return _with_subject(self.result.counts, self.subject)


def _with_subject(table: pd.DataFrame, subject: str) -> pd.DataFrame:
    table = table.copy()
    table.insert(0, "lip_subject", subject)
    return table


def lip_study(recordings: list[Recording], spec: dict, settings: LipSettings,
              mesh_path=None, subject: str = "") -> LipStudy:
    """The lip subject ``spec`` (config ``lips.subjects``) through the model: the GRID clips on
    the face mesh at ``mesh_path``, or the virtual talker's recording as read back from its
    file (checked against the talker it was simulated from)."""
    common = settings.model_kwargs()
    if spec["source"] == "grid":
        result = grid_lip_study(recordings, mesh_path, normalisation=settings.normalisation,
                                **common)
        study = LipStudy(subject, "GRID talker", result, result.heldout_landmarks)
    else:
        talker = make_virtual_talker(n_frames=spec.get("frames", 150), seed=spec.get("seed", 0))
        rec = recordings[0]
        check_round_trip(talker, rec)
        result = run_virtual(talker, rec, settings.normalisation, **common)
        study = LipStudy(subject, "Virtual lip talker", result, result.truth_recovery)
    log.info("model placement on the first frame: %s",
             {k: round(float(v), 4) for k, v in result.placement.items()})
    log.info("model units per mm (x, y, z): %s", np.round(result.model_units_per_mm, 5).tolist())
    log.info("noise variance of the regularised estimators %.4g model units^2 (%s)",
             result.noise_var, result.noise_var_choice)
    return study


def check_round_trip(talker: VirtualLipTalker, recording: Recording) -> float:
    """The largest difference (mm) between the talker's recording and ``recording`` (its file
    read back), logged; its labels must be the talker's."""
    if recording.labels != talker.recording.labels:
        raise InputError(f"{recording.source}: labels differ from the virtual talker's")
    err = float(np.max(np.abs(recording.points - talker.recording.points)))
    log.info("TRC round trip of the virtual talker: max difference %.2e mm", err)
    return err
