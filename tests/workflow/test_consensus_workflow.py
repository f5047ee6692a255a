"""The cross-subject consensus in the workflow: the smoke study's two subjects under common
names from their sheet's label maps, the job's table against the library on the same files,
and a bad map stopped at parse time in one line."""

import json

import pandas as pd
import pytest
from helpers import REPO
from test_workflow import run_snakemake

from facemotion.ingest.displacement_file import load_displacements
from facemotion.regions.consensus import SubjectPilot, consensus_design
from facemotion.regions.design import MarkerSetDesign

pytestmark = pytest.mark.workflow
CONSENSUS = "eval:\n  consensus: true\n"


def sheet_with_maps(folder, maps: dict[str, str]):
    """The smoke sheet with a label_map column; ``maps``: subject -> the map's text."""
    rows = (REPO / "config" / "smoke_subjects.tsv").read_text().rstrip("\n").split("\n")
    out = [rows[0] + "\tlabel_map"]
    for row in rows[1:]:
        sid = row.split("\t")[0]
        (folder / f"{sid}_map.tsv").write_text(maps[sid])
        out.append(f"{row}\t{sid}_map.tsv")
    (folder / "sheet.tsv").write_text("\n".join(out) + "\n")
    return folder / "sheet.tsv"


def renaming() -> str:
    """Every marker j of the virtual talker called m<j>."""
    return "label\tcommon\n" + "".join(f"{j}\tm{j}\n" for j in range(1, 58))


def test_consensus_job_pools_the_subjects_under_their_common_names(tmp_path):
    sheet = sheet_with_maps(tmp_path, {"S1": renaming(), "S2a": renaming()})
    run_snakemake(tmp_path, "--cores", "2", "results/smoke/design/consensus.tsv",
                  extra_config=CONSENSUS + f"subjects: {sheet}\n")
    res = tmp_path / "results" / "smoke"
    table = pd.read_csv(res / "design" / "consensus.tsv", sep="\t", dtype={"marker": str})
    for name in ("consensus", "consensus_subjects", "consensus_marker_set", "consensus_plot"):
        assert (res / "design" / f"{name}.meta.json").is_file(), name
    t = table.set_index("marker")
    assert t.loc["m12", "subject_labels"] == "S1:12,S2a:12"
    # the job's numbers: the library's consensus of the same per-subject files
    pilots = []
    for sid in ("S1", "S2a"):
        d = load_displacements(res / sid / "data" / "displacements.npz")
        own = MarkerSetDesign.load(res / sid / "design" / "marker_set.json")
        pilots.append(SubjectPilot(sid, sid, d, [f"m{m}" for m in d.labels], own.selected,
                                   own.expected_error_mm))
    ref = consensus_design(pilots, target_mm=1.0, resamples=1000, selection_resamples=200,
                           level=0.95,
                           on_unreached="largest")
    saved = json.loads((res / "design" / "consensus_marker_set.json").read_text())
    assert saved["selected"] == ref.design.selected
    assert saved["subjects"] == ["S1", "S2a"]
    assert t.loc[ref.design.selected, "role"].eq("placed").all()
    pd.testing.assert_series_equal(
        table["expected_error_mm"], ref.markers["expected_error_mm"], rtol=1e-5,
        check_names=False)


def test_a_map_naming_a_marker_the_subject_lacks_stops_the_study(tmp_path):
    bad = "label\tcommon\n1\tChin\n99\tNose\n"
    sheet = sheet_with_maps(tmp_path, {"S1": renaming(), "S2a": bad})
    proc = run_snakemake(tmp_path, "-n", check=False,
                         extra_config=CONSENSUS + f"subjects: {sheet}\n")
    assert proc.returncode != 0
    lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "S2a_map.tsv" in ln]
    assert len(lines) == 1 and "line 3: label '99' is not a marker of the subject" in lines[0]
    assert "subject 'S2a'" in lines[0] and not (tmp_path / "results").exists()
