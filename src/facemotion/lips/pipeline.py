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
   noise-free (sigma^2 = 0, the paper's) and regularised (sigma^2 from probabilistic PCA).
   Error: mean squared error per DOF over all free DOF of the model and over the test frames,
   against the minimal-force fits of the test frames (the paper's reference), in model units^2
   and in mm^2.

`virtual_lip_study` and `grid_lip_study` wrap it for the virtual talker and the GRID clips.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.io.recording import Recording
from facemotion.lips.fem import assemble_stiffness
from facemotion.lips.fitting import MinimalForceFitter, fit_residuals
from facemotion.lips.llse import LLSE, ppca_noise_var
from facemotion.lips.mesh import PAPER_MODEL_EXTENT, LipMesh, canonical_lip_mesh, unit_scale
from facemotion.lips.normalise import align_rigid, fit_scaled_rigid, normalise_paper, to_model
from facemotion.lips.pca import pca_svd
from facemotion.lips.virtual import VirtualLipTalker, depth_share, make_virtual_talker

VIEWS = ("xyz_8_points", "yz_all_points", "xy_all_points")
VIEW_AXES = {"xyz_8_points": (0, 1, 2), "yz_all_points": (1, 2), "xy_all_points": (0, 1)}
POINT_SETS = ("tracked_points", "mesh_nodes")
NOISES = ("noise_free", "regularised")
NOISE_GRID = (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)

# Basu & Pentland (1997), Table 1: reconstruction error per DOF in the model's normalised units,
# (first 10 modes, full covariance).
PAPER_TABLE1 = {"xyz_8_points": (1.10e-3, 7.80e-4), "yz_all_points": (7.13e-4, 4.38e-4),
                "xy_all_points": (6.70e-3, 7.50e-3)}
PAPER_COUNTS = {  # quantity: (paper value, unit, place in the paper)
    "triangles": (336, "count", "Sec. 2.1"),
    "nodes": (204, "count", "Sec. 2.1"),
    "dof": (612, "count", "Sec. 2.1"),
    "free_dof": (600, "count", "Sec. 4.1 (P has 600 columns)"),
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
    (k,) model units. `mesh` is the rest-state mesh in the model's mm coordinates; `unit_scale`
    (3,) model units per mm along x, y, z.
    """

    mesh: LipMesh
    tracked: list[str]
    displacements: np.ndarray
    goals: np.ndarray
    mean_displacement: np.ndarray
    mode_shapes: np.ndarray
    mode_sd: np.ndarray
    mode_variance_fraction: np.ndarray
    unit_scale: np.ndarray
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
    test = _frames(test_frames, F, np.arange(max(F - 10, 1), F), "test_frames")
    train = _frames(train_frames, F, np.arange(0, max(F - 10, 1)), "train_frames")
    if np.intersect1d(train, test).size:
        raise InputError("train_frames, test_frames: the training and test frames overlap")
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
    data_m = to_model(pts, R, s, t)
    fit_kw = {"E": E, "nu": nu, "ridge_factor": ridge_factor, "strip_factor": strip_factor}
    # rest state: the default model deformed to the first frame, physics re-linearised there
    rest_goal = data_m[0, cols] - mesh.nodes[tracked_nodes]
    u_rest = MinimalForceFitter(mesh, assemble_stiffness(mesh, **fit_kw), tracked).fit(
        rest_goal)[0]
    rest = mesh.with_nodes(mesh.nodes + u_rest)
    placement = {"scale_x": s[0], "scale_y": s[1], "scale_z": s[2],
                 "rotation_deg": float(np.degrees(np.arccos(np.clip(
                     (np.trace(R) - 1) / 2, -1, 1)))),
                 "rest_rms_mm": float(np.sqrt(np.mean(np.sum(rest_goal ** 2, axis=1))))}
    goals = data_m[:, cols] - rest.nodes[tracked_nodes]                 # U_g (Sec. 4)
    fitter = MinimalForceFitter(rest, assemble_stiffness(rest, **fit_kw), tracked)
    U = fitter.fit(goals)                                               # eqs. 7-10
    residuals = fit_residuals(U, goals, fitter.tracked)
    state = fitter.dofs
    k_unit = unit_scale(mesh, model_extent)                            # model units per mm
    unit_of_state = k_unit[state % 3]
    data = (U * k_unit).reshape(F, -1)[:, state]
    all_modes = pca_svd(data[train])                                    # eq. 13, PCA
    if n_modes > all_modes.n_modes:
        raise InputError(f"n_modes: {n_modes} modes requested but "
                         f"{len(train)} training frames support at most {all_modes.n_modes}")
    modes = all_modes.truncated(n_modes)
    if noise_var == "ppca":
        s2, choice = ppca_noise_var(all_modes, n_modes, data.shape[1]), "ppca"
    else:
        s2, choice = float(noise_var), "setting"
    estimators = {f"{n_modes}_modes": LLSE.from_modes(modes),
                  "full_covariance": LLSE.from_data(data[train])}
    view_points = list(view_points) if view_points is not None else tracked[:8]
    truth_state = None
    if truth is not None:
        truth = np.asarray(truth, dtype=float)
        if truth.shape != (F, mesh.n_nodes, 3):
            raise InputError(f"lip model: truth must be ({F}, {mesh.n_nodes}, 3), got "
                             f"{truth.shape}")
        truth_state = (truth * k_unit).reshape(F, -1)[:, state]
    obs = {}
    for ps in POINT_SETS:
        for v in VIEWS:
            nodes, axes = view_nodes(rest, v, ps, tracked, view_points)
            obs[v, ps] = state_positions(rest, state, nodes, axes)
    target = data[test]
    mean_shape_err = _mse_per_dof(np.broadcast_to(modes.mean, target.shape), target)

    rows = []
    for (v, ps), o in obs.items():
        for cov, est in estimators.items():
            for noise, s2v in (("noise_free", 0.0), ("regularised", s2)):
                u = est.estimate(target[:, o], o, s2v)
                row = {"view": v, "point_set": ps, "covariance": cov, "noise": noise,
                       "noise_var_model_units2": s2v, "n_observed_dof": len(o),
                       "n_evaluated_dof": data.shape[1], "n_test_frames": len(test),
                       "mse_per_dof_model_units2": _mse_per_dof(u, target),
                       "mse_per_dof_mm2": _mse_per_dof(u, target, unit_of_state),
                       "mse_mean_shape_model_units2": mean_shape_err}
                if truth_state is not None:
                    row["mse_vs_truth_model_units2"] = _mse_per_dof(u, truth_state[test])
                rows.append(row)
    recon = reconstruction_table(pd.DataFrame(rows), n_modes)

    sens = []
    for value, how in [(g, "grid") for g in noise_grid] + [(s2, choice)]:
        for (v, ps), o in obs.items():
            for cov, est in estimators.items():
                u = est.estimate(target[:, o], o, value)
                sens.append({"noise_var_model_units2": value, "choice": how, "view": v,
                             "point_set": ps, "covariance": cov,
                             "mse_per_dof_model_units2": _mse_per_dof(u, target)})
    sens = pd.DataFrame(sens)

    heldout = None
    if heldout_labels:
        heldout = _heldout_table(rest, recording, data_m, tracked, heldout_labels, U,
                                 estimators[f"{n_modes}_modes"], state, k_unit, obs, s2, test)
    truth_rec = None
    if truth_state is not None:
        err = (data - truth_state) / unit_of_state
        tru = truth_state / unit_of_state
        truth_rec = pd.DataFrame({
            "frame": np.arange(F),
            "rms_error_mm": np.sqrt(np.mean(err ** 2, axis=1) * 3),
            "rms_truth_displacement_mm": np.sqrt(np.mean(tru ** 2, axis=1) * 3),
        })
    U_modes = np.zeros((n_modes, 3 * mesh.n_nodes))
    U_modes[:, state] = modes.modes
    mean = np.zeros(3 * mesh.n_nodes)
    mean[state] = modes.mean
    fractions = modes.variances / all_modes.total_variance
    counts = counts_table(mesh, tracked, nose_label is not None,
                          F, recording.rate, train, test, n_modes, float(fractions.sum()),
                          k_unit, model_extent, E, nu, ridge_factor)
    return LipModelResult(
        mesh=rest, tracked=tracked, displacements=U, goals=goals,
        mean_displacement=mean.reshape(-1, 3), mode_shapes=U_modes.reshape(n_modes, -1, 3),
        mode_sd=np.sqrt(modes.variances), mode_variance_fraction=fractions,
        unit_scale=k_unit, noise_var=s2, noise_var_choice=choice,
        train_frames=train, test_frames=test, placement=placement,
        modes=all_modes.table().head(max(n_modes, min(all_modes.n_modes, 20))),
        fit_residuals=residuals, reconstruction=recon, noise_sensitivity=sens,
        counts=counts, heldout_landmarks=heldout, truth_recovery=truth_rec)


def reconstruction_table(rows: pd.DataFrame, n_modes: int) -> pd.DataFrame:
    """Table 1, long: adds `paper_definition` (tracked points, sigma^2 = 0: the paper's
    estimator) and, on those rows of the 10-mode and full covariance, the paper's value
    `paper_mse_per_dof_model_units2` and its place."""
    rows = rows.copy()
    rows["rmse_mm"] = np.sqrt(rows["mse_per_dof_mm2"])
    rows["paper_definition"] = (rows["point_set"] == "tracked_points") & (
        rows["noise"] == "noise_free")
    paper = []
    for _, r in rows.iterrows():
        col = {"10_modes": 0, "full_covariance": 1}.get(r["covariance"])
        ok = r["paper_definition"] and col is not None and (
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
    ext = (k_unit * (mesh.nodes.max(axis=0) - mesh.nodes.min(axis=0)))
    ours = {"triangles": mesh.n_triangles, "nodes": mesh.n_nodes, "dof": 3 * mesh.n_nodes,
            "free_dof": free, "tracked_lip_points": len(tracked), "nose_points": int(has_nose),
            "constrained_dof": 3 * len(tracked), "frames": frames, "frame_rate_hz": rate,
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
