"""The workflow as a Snakemake module of another project: a Snakefile in a different directory
imports it (`module facemotion: snakefile: ...; config: config` + `use rule * from facemotion`)
with its own config and sheet, and runs it (dry run and a real small target)."""

import os
import subprocess
import sys

import pandas as pd
import pytest
from helpers import REPO

pytestmark = pytest.mark.workflow

HOST = """\
configfile: "config/facemotion.yaml"


module facemotion:
    snakefile:
        "{snakefile}"
    config:
        config


use rule * from facemotion as facemotion_*


rule all:
    default_target: True
    input:
        "results/host/T1/qr/r_values.tsv",
        "results/host/tables/sweep_grid.tsv",
"""

CONFIG = """\
study: host
subjects: config/talkers.tsv
default_datasets: true
lips: {subjects: {}}
sweeps:
  grid:
    datasets: [T1]
    k: [2, 3]
"""

SHEET = ("subject\trecordings\tformat\thead_markers\texclude_markers\tunits\tsimulate\tseed\t"
         "n_sentences\tsentence_duration\n"
         "T1\t\tc3d\tH1,H2,H3,H4,H5,H6\tH1,H2,H3,H4,H5,H6\tmm\tS1\t7\t4\t0.6-1.0\n")


def snakemake(workdir, *args):
    cmd = [sys.executable, "-m", "snakemake", "--cores", "2", *args]
    proc = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONHASHSEED="0"))
    assert proc.returncode == 0, f"{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}"
    return proc


def test_workflow_runs_as_a_module_of_another_project(tmp_path):
    (tmp_path / "config").mkdir()
    (tmp_path / "Snakefile").write_text(HOST.format(snakefile=REPO / "Snakefile"))
    (tmp_path / "config" / "facemotion.yaml").write_text(CONFIG)
    (tmp_path / "config" / "talkers.tsv").write_text(SHEET)
    dry = snakemake(tmp_path, "-n")
    assert "facemotion_rank_markers" in dry.stdout + dry.stderr
    snakemake(tmp_path)
    r = pd.read_csv(tmp_path / "results" / "host" / "T1" / "qr" / "r_values.tsv", sep="\t")
    assert len(r) == 57 and r["marker"].is_unique  # the S1 design's 57 face markers
    sweep = pd.read_csv(tmp_path / "results" / "host" / "tables" / "sweep_grid.tsv", sep="\t")
    assert sweep["point"].tolist() == ["k~2", "k~3"]
    assert sweep["k"].tolist() == [2, 3]
    # each point's file is named by its values
    assert sorted(p.name for p in (tmp_path / "results" / "host" / "sweeps" / "grid" / "T1")
                  .glob("*.tsv")) == ["k~2.tsv", "k~3.tsv"]
    assert not (tmp_path / "results" / "host" / "virtual" / "S1").exists()  # the host's only


def test_module_finds_its_own_files_from_another_directory(tmp_path):
    """A sheet path that is not in the host project resolves in the workflow's repository."""
    (tmp_path / "config").mkdir()
    (tmp_path / "Snakefile").write_text(HOST.format(snakefile=REPO / "Snakefile").replace(
        '        "results/host/tables/sweep_grid.tsv",\n', "").replace("results/host/",
                                                                   "results/smoke_subjects/"))
    (tmp_path / "config" / "facemotion.yaml").write_text(
        "subjects: config/smoke_subjects.tsv\nlips: {subjects: {}}\n")
    assert not (tmp_path / "config" / "smoke_subjects.tsv").exists()
    # the study is named after the host's sheet
    dry = snakemake(tmp_path, "-n", "results/smoke_subjects/S1/qr/r_values.tsv")
    assert "facemotion_simulate_subject" in dry.stdout + dry.stderr
