"""Load every dataset's recordings into its displacement matrix A, with the gap check.

One job over all datasets (ordered by subject): a subject's takes are read once for all its
datasets (e.g. S2a and S2a*, the same sentences in another order); with several threads, the
subjects are loaded side by side (run_per_dataset's forked workers).
"""

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.displacement_file import save_displacements
from facemotion.ingest.loading import load_dataset
from facemotion.ingest.validation import Limits
from facemotion.plots.gaps import plot_gaps
from facemotion.study.adapter import figure_paths, run_per_dataset
from facemotion.study.provenance import save_figure, sidecar_for_existing, write_table

_TAKES = {"subject": None, "takes": {}}  # the takes of the subject being loaded


def main(sm, log, prov):
    ds = sm.params.ds
    if ds["subject"] != _TAKES["subject"]:  # datasets come grouped by subject
        _TAKES.update(subject=ds["subject"], takes={})
    recordings = list(sm.params.recordings)
    gaps, checks = sm.params.gaps, sm.params.checks
    limits = Limits(max_distance_mm=gaps["max_distance_mm"],
                    max_speed_mm_s=gaps["max_speed_mm_s"], outliers=gaps["outliers"],
                    min_take_frames=checks["min_take_frames"],
                    face_spread_mm=tuple(checks["face_spread_mm"]),
                    rate_hz=tuple(checks["rate_hz"]),
                    max_shape_rms_mm=checks["max_shape_rms_mm"])
    loaded = load_dataset(
        recordings, ds["format"], units=ds["units"], head_markers=ds["head_markers"],
        exclude_markers=ds["exclude_markers"], include_markers=ds["include_markers"],
        train=[i - 1 for i in ds["train"]], heldout=[i - 1 for i in ds["heldout"]],
        max_interp_s=sm.params.gaps["max_interp_s"], long_gaps=sm.params.gaps["long_gaps"],
        neutral=sm.params.neutral, limits=limits, sentences=ds["segments"],
        subject_prefix=ds["subject_prefix"],
        copy_markers=parse_copy_markers(ds.get("copy_markers", []), "copy_markers"),
        takes=_TAKES["takes"])
    prov.inputs = list(prov.inputs) + [r for r in recordings]
    d = loaded.displacements
    log.info("A: %d rows x %d markers from %d sentences", *d.A.shape, len(d.sentences))
    save_displacements(sm.output.npz, d)
    sidecar_for_existing(sm.output.npz, "displacements", prov)
    write_table(loaded.gap_report, sm.output.gaps, "gap_report", prov)
    write_table(loaded.sentences, sm.output.sentences, "sentences", prov)
    fig = plot_gaps(loaded.time_s, loaded.missing, loaded.filled, d.labels,
                    sentence_bounds=loaded.sentence_starts_s)
    save_figure(fig, figure_paths(sm.output, "gap_png"), "gaps", prov)


run_per_dataset(snakemake, main, group_by=lambda part: part.params.ds["subject"],  # noqa: F821
                cost=lambda part: len(part.params.recordings),
                preload=("scipy.interpolate", "ezc3d"))  # gap filling, C3D reading
