"""Recommend a reduced marker set from a dataset's sentences (docs/design.md)."""

import json

from facemotion.ingest.displacement_file import load_displacements
from facemotion.plots.marker_set import plot_design
from facemotion.regions.design import design_markers
from facemotion.regions.marker_set import protocol_text
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_artifact, write_table


def main(sm, log, prov):
    p = sm.params
    disp = load_displacements(sm.input.npz)
    ms = design_markers(disp, target_mm=p.target_mm, resamples=p.resamples,
                        selection_resamples=p.selection_resamples, level=p.level,
                        on_unreached="largest")
    ms.neutral = disp.neutral
    log.info("%s", ms.describe())
    if ms.settings["target_reached"] is False:
        log.warning("no k up to %d reaches %g mm; the design uses k = %d", ms.k,
                    p.target_mm, ms.k)
    write_table(ms.per_marker, sm.output.table, "marker_set", prov)
    text = json.dumps(ms.to_dict(), indent=1, allow_nan=False) + "\n"
    write_artifact(sm.output.marker_set, text.encode(), "marker_set", prov)
    write_artifact(sm.output.protocol, protocol_text(ms).encode(), "marker_set_protocol", prov)
    fig = plot_design(ms, title=f"{p.label}: {ms.k} markers to place; the "
                                 f"{len(ms.predicted)} others predicted")
    save_figure(fig, figure_files(sm.output, "png"), "marker_set", prov)


run_step(snakemake, main)  # noqa: F821
