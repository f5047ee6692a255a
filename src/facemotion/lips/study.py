"""Stage functions of the lip-model study (Basu & Pentland 1997); workflow scripts call these.

`run_lip_model` is the whole analysis of one recording on one mesh:

1. normalise the tracked points ('paper': nose origin + lip-plane frame per frame; 'rigid': head
   motion removed by a rigid fit of reference landmarks to frame 0; 'none');
2. rest shape = the first frame: goals U_g are the tracked points' positions minus their frame-0
   positions. The mesh (in its own frame) is placed in the data's frame by a rigid fit of its
   tracked nodes to the frame-0 tracked points;
3. minimal-force fit of every frame (eqs. 8-10);
4. PCA of the fitted displacements of the training frames (eqs. 11-13), over all free DOF;
5. LLSE of the test frames' fitted displacements from three views (paper Table 1), with the
   n-mode covariance and with the full sample covariance, at the chosen noise variance and over a
   grid of noise variances. Error = mean squared error per DOF (mm^2), averaged over the test
   frames and over all DOF (x, y, z) of the lip-band nodes (outer, lip, inner; the mouth strip is
   not part of the lip and is left out), in the data's lip frame.

`virtual_lip_study` and `grid_lip_study` wrap it for the virtual talker and the GRID clips.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.lips.fem import assemble_stiffness
from facemotion.lips.fitting import MinimalForceFitter, fit_residuals
from facemotion.lips.llse import LLSE, ppca_noise_var
from facemotion.lips.mesh import LipMesh, canonical_lip_mesh
from facemotion.lips.modes import pca_svd
from facemotion.lips.normalise import align_rigid, kabsch, normalise_paper
from facemotion.lips.virtual import VirtualLipTalker, make_virtual_talker
from facemotion.recording import Recording

VIEWS = ("xyz_8_points", "yz_all_points", "xy_all_points")
NOISE_GRID_MM2 = (0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)

# GRID talker: 16 tracked lip landmarks of the canonical mesh (outer contour first: its 8 points
# are the 8-point view), and the reference landmarks for the rigid head fit (data README).
GRID_TRACKED = ["L061", "L291", "L000", "L017", "L040", "L270", "L091", "L321",
                "L078", "L308", "L013", "L014", "L081", "L311", "L178", "L402"]
GRID_REFERENCE = ["L006", "L168", "L197", "L195", "L010", "L151", "L009",
                  "L033", "L133", "L263", "L362"]


@dataclass
class LipModelResult:
    """Everything `run_lip_model` measured.

    Tables: `modes` (mode, variance, cumulative_fraction), `fit_residuals` (frame, max/rms
    residual mm), `reconstruction` (index view), `noise_sensitivity` (noise_var_mm2, view,
    errors), `heldout_landmarks` (view, landmark, rms_error_mm; None without held-out
    landmarks), `truth_recovery` (per frame error of the fit against a planted truth; None
    without one). Arrays: `displacements` (frames, N, 3) fitted, `mean_displacement` (N, 3) and
    `mode_shapes` (k, N, 3) (unit-norm modes; zero on fixed nodes), `mode_sd` (k,) mm.
    `mesh` is the mesh as placed in the data's frame.
    """

    mesh: LipMesh
    tracked: list[str]
    displacements: np.ndarray
    goals: np.ndarray
    mean_displacement: np.ndarray
    mode_shapes: np.ndarray
    mode_sd: np.ndarray
    noise_var: float
    noise_var_choice: str
    train_frames: np.ndarray
    test_frames: np.ndarray
    placement_rms_mm: float
    modes: pd.DataFrame
    fit_residuals: pd.DataFrame
    reconstruction: pd.DataFrame
    noise_sensitivity: pd.DataFrame
    heldout_landmarks: pd.DataFrame | None = None
    truth_recovery: pd.DataFrame | None = None


def _frames(frames, n: int, default: np.ndarray, name: str) -> np.ndarray:
    f = default if frames is None else np.asarray(list(frames), dtype=int)
    if f.ndim != 1 or len(f) == 0:
        raise InputError(f"lip model setting {name}: no frames selected")
    if f.min() < 0 or f.max() >= n:
        raise InputError(f"lip model setting {name}: frames must be in 0..{n - 1} "
                         f"(0-based), got {f.min()}..{f.max()}")
    return f


def view_dofs(mesh: LipMesh, state_dofs: np.ndarray, view: str,
              view_points: list[str]) -> np.ndarray:
    """Positions in the state vector (free DOF) of the DOF a view observes."""
    if view == "xyz_8_points":
        nodes, axes = mesh.indices(view_points), [0, 1, 2]
    elif view == "yz_all_points":
        nodes, axes = mesh.band_nodes, [1, 2]
    elif view == "xy_all_points":
        nodes, axes = mesh.band_nodes, [0, 1]
    else:
        raise InputError(f"lip model setting views: unknown view {view!r} (allowed {VIEWS})")
    return _state_positions(mesh, state_dofs, nodes, axes)


def _state_positions(mesh: LipMesh, state_dofs: np.ndarray, nodes: np.ndarray,
                     axes: list[int]) -> np.ndarray:
    where = -np.ones(3 * mesh.n_nodes, dtype=int)
    where[state_dofs] = np.arange(len(state_dofs))
    pos = where[(3 * np.asarray(nodes)[:, None] + np.asarray(axes)).ravel()]
    if np.any(pos < 0):
        raise InputError(f"{mesh.name}: a view observes a fixed node")
    return pos


def _normalise(recording: Recording, normalisation: str, mesh: LipMesh, tracked: list[str],
               nose_label: str | None, reference_labels: list[str] | None) -> np.ndarray:
    pts = recording.points
    if normalisation == "paper":
        if nose_label is None:
            raise InputError("lip model setting nose_label: the paper's normalisation needs "
                             "a nose point")
        tr = mesh.indices(tracked)
        part = mesh.part[tr]
        cols = np.array([recording.index(t) for t in tracked])
        corner_nodes = tr[part == "corner"]
        if len(corner_nodes) < 2:
            raise InputError("lip model: the paper's normalisation needs both mouth corners "
                             "among the tracked points")
        xs = mesh.nodes[corner_nodes, 0]
        a = cols[list(tr).index(corner_nodes[np.argmin(xs)])]
        b = cols[list(tr).index(corner_nodes[np.argmax(xs)])]
        return normalise_paper(pts, recording.index(nose_label), cols[part == "upper"],
                               cols[part == "lower"], (a, b), source=recording.source)
    if normalisation == "rigid":
        if not reference_labels:
            raise InputError("lip model setting reference_labels: rigid head alignment needs "
                             "reference landmarks")
        ref = [recording.index(r) for r in reference_labels]
        return align_rigid(pts, np.array(ref), source=recording.source)[0]
    if normalisation == "none":
        return pts
    raise InputError(f"lip model setting normalisation: {normalisation!r} is not one of "
                     f"'paper', 'rigid', 'none'")


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a - b) ** 2))


def run_lip_model(mesh: LipMesh, recording: Recording, tracked_labels: list[str], *,
                  normalisation: str = "paper", nose_label: str | None = None,
                  reference_labels: list[str] | None = None, train_frames=None,
                  test_frames=None, n_modes: int = 10, noise_var: float | str = "ppca",
                  views: tuple[str, ...] = VIEWS, view_points: list[str] | None = None,
                  heldout_labels: list[str] | None = None, truth: np.ndarray | None = None,
                  E: float = 1.0, nu: float = 0.01, ridge_factor: float = 2.0,
                  strip_factor: float = 0.5,
                  noise_grid: tuple[float, ...] = NOISE_GRID_MM2) -> LipModelResult:
    """Fit, learn modes and reconstruct from views; see the module docstring.

    Frames are 0-based; defaults: train on all but the last 10 frames, test on the last 10
    (the paper: 1-140 and 141-150 of 150). noise_var: mm^2, or 'ppca' (variance left out by
    the n modes per remaining DOF, see `llse.ppca_noise_var`); the same value is used for the
    full-covariance estimate. view_points: the 8-point view's nodes (default: the first 8
    tracked). truth: planted displacements (frames, N, 3) in the mesh's own frame.
    """
    tracked = [str(t) for t in tracked_labels]
    if len(tracked) != len(set(tracked)):
        raise InputError(f"lip model setting tracked_labels: repeated labels in {tracked}")
    F = recording.n_frames
    test = _frames(test_frames, F, np.arange(max(F - 10, 1), F), "test_frames")
    train = _frames(train_frames, F, np.arange(0, max(F - 10, 1)), "train_frames")
    if np.intersect1d(train, test).size:
        raise InputError("lip model settings train_frames/test_frames overlap")
    tracked_nodes = mesh.indices(tracked)  # names a label that is not a node
    cols = [recording.index(t) for t in tracked]
    pts = _normalise(recording, normalisation, mesh, tracked, nose_label, reference_labels)
    if not np.all(np.isfinite(pts[:, cols])):
        f, j = np.argwhere(~np.isfinite(pts[:, cols]).all(axis=2))[0]
        raise InputError(f"{recording.source}: tracked point {tracked[j]} is missing in "
                         f"frame {f}")
    # rest shape = frame 0; place the mesh in the data's frame by its tracked nodes
    rest = pts[0, cols]
    R0, t0 = kabsch(mesh.nodes[tracked_nodes], rest)
    placed = mesh.with_nodes(mesh.nodes @ R0.T + t0)
    placement_rms = float(np.sqrt(np.mean(np.sum(
        (placed.nodes[tracked_nodes] - rest) ** 2, axis=1))))
    goals = pts[:, cols] - rest
    K = assemble_stiffness(placed, E=E, nu=nu, ridge_factor=ridge_factor,
                           strip_factor=strip_factor)
    fitter = MinimalForceFitter(placed, K, tracked)
    U = fitter.fit(goals)                                               # eqs. 8-10
    residuals = fit_residuals(U, goals, fitter.tracked)
    state = fitter.dofs
    data = U.reshape(F, -1)[:, state]
    all_modes = pca_svd(data[train])                                    # eqs. 11-13
    if n_modes > all_modes.n_modes:
        raise InputError(f"lip model setting n_modes: {n_modes} modes requested but "
                         f"{len(train)} training frames support at most {all_modes.n_modes}")
    modes = all_modes.truncated(n_modes)
    if noise_var == "ppca":
        s2, choice = ppca_noise_var(all_modes, n_modes, data.shape[1]), "ppca"
    else:
        s2, choice = float(noise_var), "setting"
    est_k, est_full = LLSE.from_modes(modes), LLSE.from_data(data[train])
    view_points = list(view_points) if view_points is not None else tracked[:8]
    band = _state_positions(placed, state, placed.band_nodes, [0, 1, 2])
    truth_state = None
    if truth is not None:
        truth = np.asarray(truth, dtype=float)
        if truth.shape != (F, mesh.n_nodes, 3):
            raise InputError(f"lip model: truth must be ({F}, {mesh.n_nodes}, 3), got "
                             f"{truth.shape}")
        truth_state = (truth @ R0.T).reshape(F, -1)[:, state]
    obs = {v: view_dofs(placed, state, v, view_points) for v in views}
    target = data[test]
    kname = f"{n_modes}_modes"

    def errors(s2v: float) -> list[dict]:
        rows = []
        for v in views:
            y = target[:, obs[v]]
            uk, uf = est_k.estimate(y, obs[v], s2v), est_full.estimate(y, obs[v], s2v)
            row = {"view": v, f"error_{kname}": _mse(uk[:, band], target[:, band]),
                   "error_full_covariance": _mse(uf[:, band], target[:, band])}
            if truth_state is not None:
                t = truth_state[test][:, band]
                row[f"truth_error_{kname}"] = _mse(uk[:, band], t)
                row["truth_error_full_covariance"] = _mse(uf[:, band], t)
            rows.append(row)
        return rows

    recon = pd.DataFrame(errors(s2)).set_index("view")
    recon[f"rms_{kname}_mm"] = np.sqrt(recon[f"error_{kname}"])
    recon["rms_full_covariance_mm"] = np.sqrt(recon["error_full_covariance"])
    recon["error_mean_shape"] = _mse(np.broadcast_to(modes.mean[band], target[:, band].shape),
                                     target[:, band])
    recon["n_observed_dof"] = [len(obs[v]) for v in views]
    recon["n_evaluated_dof"] = len(band)
    recon["noise_var_mm2"] = s2
    recon["noise_var_choice"] = choice
    sens = []
    for value, how in [(g, "grid") for g in noise_grid] + [(s2, choice)]:
        for row in errors(value):
            sens.append({"noise_var_mm2": value, "choice": how, **row})
    sens = pd.DataFrame(sens)

    heldout = None
    if heldout_labels:
        heldout = _heldout_table(placed, recording, pts, rest, cols, tracked, heldout_labels,
                                 U, est_k, state, obs, s2, test)
    truth_rec = None
    if truth_state is not None:
        err = data[:, band] - truth_state[:, band]
        truth_rec = pd.DataFrame({
            "frame": np.arange(F),
            "rms_error_mm": np.sqrt(np.mean(err ** 2, axis=1) * 3),
            "rms_truth_displacement_mm": np.sqrt(np.mean(truth_state[:, band] ** 2, axis=1) * 3),
        })
    U_modes = np.zeros((n_modes, 3 * mesh.n_nodes))
    U_modes[:, state] = modes.modes
    mean = np.zeros(3 * mesh.n_nodes)
    mean[state] = modes.mean
    return LipModelResult(
        mesh=placed, tracked=tracked, displacements=U, goals=goals,
        mean_displacement=mean.reshape(-1, 3), mode_shapes=U_modes.reshape(n_modes, -1, 3),
        mode_sd=np.sqrt(modes.variances), noise_var=s2, noise_var_choice=choice,
        train_frames=train, test_frames=test, placement_rms_mm=placement_rms,
        modes=all_modes.table().head(max(n_modes, min(all_modes.n_modes, 20))),
        fit_residuals=residuals, reconstruction=recon, noise_sensitivity=sens,
        heldout_landmarks=heldout, truth_recovery=truth_rec)


def _heldout_table(mesh: LipMesh, recording: Recording, pts: np.ndarray, rest: np.ndarray,
                   cols: list[int], tracked: list[str], heldout: list[str], U: np.ndarray,
                   est: LLSE, state: np.ndarray, obs: dict[str, np.ndarray], s2: float,
                   test: np.ndarray) -> pd.DataFrame:
    """RMS 3-D error (mm, test frames) at landmarks that were not tracked.

    Measured displacement: the landmark's normalised position minus its frame-0 position.
    Predictors: the minimal-force fit from the tracked points, and the n-mode LLSE from each
    view, whose observations are the measured displacements of the observed nodes where the
    recording has them (all of them for GRID) and the fitted ones otherwise.
    """
    bad = sorted(set(heldout) & set(tracked))
    if bad:
        raise InputError(f"lip model setting heldout_labels: {bad} are tracked, not held out")
    h_nodes = mesh.indices(heldout)
    h_cols = [recording.index(h) for h in heldout]
    measured = pts[:, h_cols] - pts[0, h_cols]
    if not np.all(np.isfinite(measured[test])):
        raise InputError(f"{recording.source}: a held-out landmark is missing in a test frame")
    F = len(U)
    meas_state = U.reshape(F, -1)[:, state].copy()
    where = -np.ones(3 * mesh.n_nodes, dtype=int)
    where[state] = np.arange(len(state))
    for j, label in enumerate(mesh.labels):
        if label in recording.labels and where[3 * j] >= 0:
            c = recording.index(label)
            meas_state[:, where[3 * j:3 * j + 3]] = pts[:, c] - pts[0, c]
    h_state = where[(3 * h_nodes[:, None] + np.arange(3)).ravel()]
    preds = {"minimal_force_fit": U[test][:, h_nodes]}
    for v, o in obs.items():
        u = est.estimate(meas_state[test][:, o], o, s2)
        preds[v] = u[:, h_state].reshape(len(test), len(h_nodes), 3)
    rows = []
    for v, p in preds.items():
        err = np.sqrt(np.mean(np.sum((p - measured[test]) ** 2, axis=2), axis=0))
        disp = np.sqrt(np.mean(np.sum(measured[test] ** 2, axis=2), axis=0))
        for j, label in enumerate(heldout):
            rows.append({"view": v, "landmark": label, "rms_error_mm": err[j],
                         "rms_displacement_mm": disp[j]})
    return pd.DataFrame(rows)


def virtual_lip_study(seed: int = 0, normalisation: str = "paper",
                      talker_kwargs: dict | None = None,
                      **model_kwargs) -> tuple[VirtualLipTalker, LipModelResult]:
    """The virtual talker through the model. normalisation 'paper' (nose + lip planes, the
    paper's way) or 'rigid' (rigid fit of the nose and the three head points)."""
    talker = make_virtual_talker(seed=seed, **(talker_kwargs or {}))
    result = run_lip_model(talker.mesh, talker.recording, talker.tracked_labels,
                           normalisation=normalisation, nose_label=talker.nose_label,
                           reference_labels=talker.head_labels,
                           view_points=talker.view_labels, truth=talker.truth, **model_kwargs)
    return talker, result


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


def grid_lip_mesh(obj_path, recording: Recording, reference_labels: list[str] = GRID_REFERENCE,
                  strip_rings: int = 2) -> LipMesh:
    """The canonical lip band's topology with the talker's own head-aligned frame-0 landmarks
    as the rest geometry, plus the mouth strip."""
    aligned = align_rigid(recording.points, np.array([recording.index(r)
                                                      for r in reference_labels]),
                          source=recording.source)[0]
    band = canonical_lip_mesh(obj_path, strip_rings=strip_rings)
    labels = [band.labels[i] for i in band.band_nodes]
    nodes = {lab: aligned[0, recording.index(lab)] for lab in labels}
    return canonical_lip_mesh(obj_path, strip_rings=strip_rings, band_nodes=nodes)


def grid_lip_study(recordings: list[Recording], obj_path,
                   tracked_labels: list[str] = GRID_TRACKED,
                   reference_labels: list[str] = GRID_REFERENCE,
                   **model_kwargs) -> LipModelResult:
    """The GRID talker's clips, concatenated (2 x 75 = 150 frames; train 0-139, test 140-149
    as in the paper), on the canonical lip band; every untracked band landmark is held out."""
    rec = concatenate_recordings(recordings)
    mesh = grid_lip_mesh(obj_path, rec, reference_labels)
    heldout = [mesh.labels[i] for i in mesh.band_nodes if mesh.labels[i] not in tracked_labels]
    return run_lip_model(mesh, rec, tracked_labels, normalisation="rigid",
                         reference_labels=reference_labels, view_points=tracked_labels[:8],
                         heldout_labels=heldout, **model_kwargs)
