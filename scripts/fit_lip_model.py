"""Fit the lip model (Basu & Pentland 1997) and reconstruct from partial views (Table 1).

One job for all lip subjects (run_per_dataset: each subject on its own, as if in a job of its
own, with the wildcard lip_subject)."""

import numpy as np

from facemotion.errors import InputError
from facemotion.io.trc import read_trc
from facemotion.lips.pipeline import grid_lip_study, run_virtual
from facemotion.lips.virtual import make_virtual_talker
from facemotion.plots.lips import plot_mesh, plot_modes
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table
from facemotion.study.sheet import parse_sentences


def main(sm, log, prov):
    p = sm.params.lip
    spec = p["subject"]
    subject = sm.wildcards.lip_subject
    recordings = [read_trc(f) for f in sm.input.tracks]
    n = sum(r.n_frames for r in recordings)
    train = np.array(parse_sentences(p["train_frames"], n, "lips.train_frames"))
    test = np.array(parse_sentences(p["test_frames"], n, "lips.test_frames"))
    noise_var = "ppca" if p["noise_var"] == "auto" else p["noise_var"]
    if isinstance(noise_var, str) and noise_var != "ppca":
        raise InputError(f"setting lips.noise_var: {noise_var!r} is neither a number nor 'auto'")
    extent = p["model_extent"]
    common = {"train_frames": train, "test_frames": test, "n_modes": p["n_modes"],
              "noise_var": noise_var, "E": p["E"], "nu": p["nu"],
              "model_extent": None if extent is None else tuple(extent),
              "noise_grid": tuple(p["noise_var_sweep"])}
    if spec["source"] == "grid":
        result = grid_lip_study(recordings, sm.input.mesh, normalisation=p["normalisation"],
                                **common)
        points = result.heldout_landmarks
        name = "GRID talker"
    else:
        talker = make_virtual_talker(n_frames=spec.get("frames", 150), seed=spec.get("seed", 0))
        rec = recordings[0]
        if rec.labels != talker.recording.labels:
            raise InputError(f"{rec.source}: labels differ from the virtual talker's")
        err = float(np.max(np.abs(rec.points - talker.recording.points)))
        log.info("TRC round trip of the virtual talker: max difference %.2e mm", err)
        result = run_virtual(talker, rec, p["normalisation"], **common)
        points = result.truth_recovery
        name = "Virtual lip talker"
    log.info("model placement on the first frame: %s", {k: round(float(v), 4) for k, v in
                                                          result.placement.items()})
    log.info("model units per mm (x, y, z): %s", np.round(result.unit_scale, 5).tolist())
    log.info("noise variance of the regularised estimators %.4g model units^2 (%s)",
             result.noise_var, result.noise_var_choice)
    save_figure(plot_mesh(result.mesh, result.tracked, result.mesh.fixed),
                figure_files(sm.output, "mesh_png"), "lip_mesh", prov)
    write_table(result.modes, sm.output.modes, "lip_modes", prov)
    title = (f"{name} ({subject}): mean displacement and characteristic modes "
             f"(Basu & Pentland 1997, Fig. 9)")
    save_figure(plot_modes(result.mean_displacement, result.mode_shapes, result.mesh,
                           result.mode_sd, result.mode_variance_fraction, result.unit_scale,
                           title=title),
                figure_files(sm.output, "modes_png"), "lip_modes", prov)
    write_table(result.fit_residuals, sm.output.fit_residuals, "lip_fit_residuals", prov)
    recon = result.reconstruction
    recon.insert(0, "lip_subject", subject)
    write_table(recon, sm.output.reconstruction, "lip_reconstruction", prov)
    counts = result.counts
    counts.insert(0, "lip_subject", subject)
    write_table(counts, sm.output.counts, "lip_model_counts", prov)
    write_table(result.noise_sensitivity, sm.output.noise_sensitivity, "summary", prov)
    write_table(points, sm.output.heldout_points, "summary", prov)


run_step(snakemake, main)  # noqa: F821
