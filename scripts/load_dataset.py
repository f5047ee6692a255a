"""Load a dataset's recordings into its displacement matrix A, with the gap check."""

import pandas as pd

from facemotion.ingest.copy_fill import parse_copy_markers
from facemotion.ingest.displacement_file import save_displacements
from facemotion.ingest.loading import load_dataset
from facemotion.plots.gaps import plot_gaps
from facemotion.ranking.filled import LEFT_OUT, marker_fractions
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, sidecar_for_existing, write_table
from facemotion.study.settings import limits_from_config


def leave_out_filled(loaded, limit, load, exclude, log):
    """With qr.max_filled_fraction set: A again without the markers filled more than it (the
    ranking and every step after it then never sees them); they stay in the gap report, their
    fill_method 'left out'."""
    if limit is None:
        return loaded
    fr = marker_fractions(loaded.gap_report)["filled_fraction"]
    over = [str(m) for m in fr.index[fr.to_numpy() > limit]]
    if not over:
        return loaded
    log.warning("left out of A (qr.max_filled_fraction = %g): %s", limit,
                ", ".join(f"{m} {100 * fr[m]:.0f} %% filled" for m in over))
    report = loaded.gap_report
    gone = report[report["marker"].astype(str).isin(over)].assign(fill_method=LEFT_OUT)
    loaded = load(exclude + over, left_out=over)
    loaded.gap_report = pd.concat([loaded.gap_report, gone], ignore_index=True)
    return loaded


def main(sm, log, prov):
    ds = sm.params.ds
    # the params name files as the study records them; files_at says where they lie
    at = dict(sm.params.files_at)
    names = {path: name for name, path in at.items()}
    recordings = [at.get(r, r) for r in sm.params.recordings]
    segments = ds["segments"] and [{**s, "take": at.get(s["take"], s["take"])}
                                   for s in ds["segments"]]
    gaps = sm.params.gaps
    takes = {}  # read once, also when markers mostly made up are left out and A is redone

    copies = parse_copy_markers(ds["copy_markers"], "copy_markers")

    def load(exclude, left_out=()):
        return load_dataset(
            recordings, ds["format"], units=ds["units"], head_markers=ds["head_markers"],
            exclude_markers=exclude, include_markers=ds["include_markers"],
            train=[i - 1 for i in ds["train"]], heldout=[i - 1 for i in ds["heldout"]],
            max_interp_s=gaps["max_interp_s"], long_gaps=gaps["long_gaps"],
            neutral=sm.params.neutral, limits=limits_from_config(gaps, sm.params.checks),
            sentences=segments, subject_prefix=ds["subject_prefix"], rate=ds.get("rate"),
            copy_markers=[(t, c) for t, c in copies if t not in left_out], takes=takes)

    loaded = load(list(ds["exclude_markers"]))
    loaded = leave_out_filled(loaded, sm.params.max_filled_fraction, load,
                              list(ds["exclude_markers"]), log)
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
