"""Load a dataset's recordings into its displacement matrix A, with the gap check."""

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.displacement_file import save_displacements
from facemotion.ingest.loading import load_dataset
from facemotion.plots.gaps import plot_gaps
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, sidecar_for_existing, write_table
from facemotion.study.settings import limits_from_config


def main(sm, log, prov):
    ds = sm.params.ds
    # the params name files as the study records them; files_at says where they lie
    at = dict(sm.params.files_at)
    names = {path: name for name, path in at.items()}
    recordings = [at.get(r, r) for r in sm.params.recordings]
    segments = ds["segments"] and [{**s, "take": at.get(s["take"], s["take"])}
                                   for s in ds["segments"]]
    gaps = sm.params.gaps
    loaded = load_dataset(
        recordings, ds["format"], units=ds["units"], head_markers=ds["head_markers"],
        exclude_markers=ds["exclude_markers"], include_markers=ds["include_markers"],
        train=[i - 1 for i in ds["train"]], heldout=[i - 1 for i in ds["heldout"]],
        max_interp_s=gaps["max_interp_s"], long_gaps=gaps["long_gaps"],
        neutral=sm.params.neutral, limits=limits_from_config(gaps, sm.params.checks),
        sentences=segments, subject_prefix=ds["subject_prefix"],
        copy_markers=parse_copy_markers(ds["copy_markers"], "copy_markers"))
    prov.inputs = list(prov.inputs) + recordings
    d = loaded.displacements
    log.info("A: %d rows x %d markers from %d sentences", *d.A.shape, len(d.sentences))
    save_displacements(sm.output.npz, d)
    sidecar_for_existing(sm.output.npz, "displacements", prov)
    write_table(loaded.gap_report, sm.output.gap_report, "gap_report", prov)
    sentences = loaded.sentences.assign(
        file=[names.get(f, f) for f in loaded.sentences["file"]])
    write_table(sentences, sm.output.sentences, "sentences", prov)
    fig = plot_gaps(loaded.time_s, loaded.missing, loaded.filled, d.labels,
                    sentence_bounds=loaded.sentence_starts_s)
    save_figure(fig, figure_files(sm.output, "gaps"), "gaps", prov)


run_step(snakemake, main)  # noqa: F821
