"""One marker set for the study's subjects together (docs/design.md)."""

import json

from facemotion.ingest.displacement_file import load_displacements
from facemotion.plots.marker_set import plot_design
from facemotion.regions.consensus import (
    LabelMap,
    SubjectPilot,
    common_labels,
    consensus_design,
)
from facemotion.regions.design import MarkerSetDesign
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_artifact, write_table


def pilot(spec, npz, marker_set) -> SubjectPilot:
    disp = load_displacements(npz)
    lm = spec["label_map"]
    lm = None if lm is None else LabelMap(lm["common"], lm["line"], lm["source"])
    # the map's labels were checked against the subject's files when the study started
    common = common_labels(disp.labels, lm, known=[] if lm is None else lm.common)
    own = MarkerSetDesign.load(marker_set)
    return SubjectPilot(spec["subject"], spec["dataset"], disp, common, own.selected,
                        own.expected_error_mm)


def main(sm, log, prov):
    p = sm.params
    pilots = [pilot(s, n, m) for s, n, m in
              zip(p.subjects, sm.input.npz, sm.input.marker_sets, strict=True)]
    con = consensus_design(pilots, target_mm=p.target_mm, resamples=p.resamples,
                           selection_resamples=p.selection_resamples,
                           level=p.level, on_unreached="largest")
    ms = con.design
    log.info("%s", ms.describe())
    if ms.settings["not_in_every_subject"]:
        log.warning("markers not in every subject, left out of the consensus: %s",
                    ", ".join(ms.settings["not_in_every_subject"]))
    if ms.settings["target_reached"] is False:
        log.warning("no k up to %d reaches %g mm; the consensus uses k = %d", ms.k,
                    p.target_mm, ms.k)
    write_table(con.markers, sm.output.table, "design_consensus", prov)
    write_table(con.subjects, sm.output.subjects, "design_consensus_subjects", prov)
    text = json.dumps(ms.to_dict(), indent=1, allow_nan=False) + "\n"
    write_artifact(sm.output.marker_set, text.encode(), "marker_set", prov)
    fig = plot_design(ms, title=f"{len(pilots)} subjects: {ms.k} markers to place; the "
                                 f"{len(ms.predicted)} others predicted")
    save_figure(fig, figure_files(sm.output, "png"), "marker_set", prov)


run_step(snakemake, main)  # noqa: F821
