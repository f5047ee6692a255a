"""Fit the lip model (Basu & Pentland 1997) and reconstruct from partial views (Table 1).

One job for all lip subjects (run_per_dataset: each subject on its own, as if in a job of its
own, with the wildcard lip_subject)."""

from facemotion.io.trc import read_trc
from facemotion.lips.pipeline import lip_study
from facemotion.plots.lips import plot_mesh, plot_modes
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table
from facemotion.study.settings import lip_settings


def main(sm, log, prov):
    p = sm.params.lip
    recordings = [read_trc(f) for f in sm.input.tracks]
    settings = lip_settings(p, sum(r.n_frames for r in recordings))
    study = lip_study(recordings, p["subject"], settings, mesh_path=getattr(sm.input, "mesh", None),
                      subject=sm.wildcards.lip_subject)
    result = study.result
    save_figure(plot_mesh(result.mesh, result.tracked, result.mesh.fixed),
                figure_files(sm.output, "mesh_png"), "lip_mesh", prov)
    write_table(result.modes, sm.output.modes, "lip_modes", prov)
    save_figure(plot_modes(result.mean_displacement, result.mode_shapes, result.mesh,
                           result.mode_sd, result.mode_variance_fraction, result.model_units_per_mm,
                           title=study.modes_title),
                figure_files(sm.output, "modes_png"), "lip_modes", prov)
    write_table(result.fit_residuals, sm.output.fit_residuals, "lip_fit_residuals", prov)
    write_table(study.reconstruction, sm.output.reconstruction, "lip_reconstruction", prov)
    write_table(study.counts, sm.output.counts, "lip_model_counts", prov)
    write_table(result.noise_sensitivity, sm.output.noise_sensitivity, "summary", prov)
    write_table(study.heldout_points, sm.output.heldout_points, "summary", prov)


run_step(snakemake, main)  # noqa: F821
