"""Fit the lip model (Basu & Pentland 1997) and reconstruct from partial views (Table 1)."""

import numpy as np

from facemotion.errors import InputError
from facemotion.lips.plots import plot_mesh, plot_modes
from facemotion.lips.study import grid_lip_study, run_lip_model
from facemotion.lips.virtual import make_virtual_talker
from facemotion.provenance import save_figure, write_table
from facemotion.readers import read_trc
from facemotion.snakemake_adapter import run_step
from facemotion.subjects import parse_sentences


def main(sm, log, prov):
    p = sm.params.lip
    spec = p["subject"]
    recordings = [read_trc(f) for f in sm.input.tracks]
    n = sum(r.n_frames for r in recordings)
    train = np.array(parse_sentences(p["train_frames"], n, "lips.train_frames"))
    test = np.array(parse_sentences(p["test_frames"], n, "lips.test_frames"))
    noise_var = "ppca" if p["noise_var"] == "auto" else p["noise_var"]
    if isinstance(noise_var, str) and noise_var != "ppca":
        raise InputError(f"setting lips.noise_var: {noise_var!r} is neither a number nor 'auto'")
    common = {"train_frames": train, "test_frames": test, "n_modes": p["n_modes"],
              "noise_var": noise_var, "E": p["E"], "nu": p["nu"],
              "noise_grid": tuple(p["noise_var_sweep"])}
    if spec["source"] == "grid":
        result = grid_lip_study(recordings, sm.input.mesh, **common)
        points = result.heldout_landmarks
    else:
        talker = make_virtual_talker(n_frames=spec.get("frames", 150), seed=spec.get("seed", 0))
        rec = recordings[0]
        if rec.labels != talker.recording.labels:
            raise InputError(f"{rec.source}: labels differ from the virtual talker's")
        err = float(np.max(np.abs(rec.points - talker.recording.points)))
        log.info("TRC round trip of the virtual talker: max difference %.2e mm", err)
        result = run_lip_model(talker.mesh, rec, talker.tracked_labels,
                               normalisation=p["normalisation"], nose_label=talker.nose_label,
                               reference_labels=talker.head_labels,
                               view_points=talker.view_labels, truth=talker.truth, **common)
        points = result.truth_recovery
    log.info("noise variance %.4g mm^2 (%s)", result.noise_var, result.noise_var_choice)
    fixed = result.mesh.fixed
    save_figure(plot_mesh(result.mesh, result.tracked, fixed),
                [sm.output.mesh_png, sm.output.mesh_pdf], "lip_mesh", prov)
    write_table(result.modes, sm.output.modes, "lip_modes", prov)
    save_figure(plot_modes(result.mean_displacement, result.mode_shapes, result.mesh,
                           result.mode_sd),
                [sm.output.modes_png, sm.output.modes_pdf], "lip_modes", prov)
    write_table(result.fit_residuals, sm.output.residuals, "lip_fit_residuals", prov)
    write_table(result.reconstruction.reset_index(), sm.output.reconstruction,
                "lip_reconstruction", prov)
    write_table(result.noise_sensitivity, sm.output.sensitivity, "summary", prov)
    write_table(points, sm.output.heldout, "summary", prov)


run_step(snakemake, main)  # noqa: F821
