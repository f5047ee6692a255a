"""No setting or sheet value places a file outside the study root: every name that becomes
part of a path is an identifier by schema, and every output path is checked, symbolic links
included, before a job writes anything."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest
import yaml
from helpers import SCHEMAS

from facemotion.errors import InputError
from facemotion.study.outputs import check_inside_study
from facemotion.study.settings import validate_config
from facemotion.study.sheet import read_subject_sheet

SCHEMA = SCHEMAS / "config.schema.yaml"
BAD_NAMES = ["../../../../OUT", "..", "/tmp/abs", "", " ", "a/b", ".hidden"]


def _config(**extra):
    cfg = yaml.safe_load((SCHEMA.parent.parent.parent / "config" / "smoke.yaml").read_text())
    cfg.update(extra)
    return cfg


@pytest.mark.parametrize("name", BAD_NAMES)
@pytest.mark.parametrize("where", ["study", "datasets", "sweeps", "lips.subjects",
                                   "marker_subsets"])
def test_every_name_that_becomes_a_path_is_an_identifier(where, name):
    cfg = {
        "study": lambda: _config(study=name),
        "datasets": lambda: _config(datasets={name: {"subject": "S1"}}),
        "sweeps": lambda: _config(sweeps={name: {"k": [2]}}),
        "lips.subjects": lambda: _config(lips={"subjects": {name: {"source": "virtual"}}}),
        "marker_subsets": lambda: _config(
            sweeps={"s": {"marker_subsets": {name: ["A", "B"]}}}),
    }[where]()
    with pytest.raises(InputError, match=r"^setting [a-z.]+(\.s\.marker_subsets)?: .* is not "
                                         r"a name of letters, digits.*output paths"):
        validate_config(cfg, SCHEMA)


def test_a_good_name_passes():
    validate_config(_config(sweeps={"k.sweep-1": {"k": [2]}}), SCHEMA)


@pytest.mark.parametrize("name", ["../x", "..", "/abs", "", "a/b"])
def test_sheet_subject_ids_are_identifiers(tmp_path, name):
    (tmp_path / "t.c3d").write_bytes(b"")
    sheet = tmp_path / "s.tsv"
    sheet.write_text("subject\trecordings\tformat\thead_markers\texclude_markers\n"
                     f"{name}\tt.c3d\tc3d\t\t\n")
    with pytest.raises(InputError, match="subject id .* must be letters"):
        read_subject_sheet(sheet)


def test_output_paths_under_the_root_pass(tmp_path):
    (tmp_path / "results" / "st").mkdir(parents=True)
    check_inside_study(["results/st/S1/qr/rank.tsv", "results/st/logs/x.log"], tmp_path)


@pytest.mark.parametrize("path, match", [
    ("results/st/../../../OUT/k~2.tsv", "outside the study root"),
    ("/etc/passwd", "outside the study root"),
    ("..", "outside the study root"),
    ("", "an empty name"),
    ("results/st//x.tsv", "an empty name"),
    ("results/st/ /x.tsv", "an empty name"),
])
def test_output_paths_outside_are_refused(tmp_path, path, match):
    with pytest.raises(InputError, match=match):
        check_inside_study([path], tmp_path)


def test_a_symbolic_link_inside_the_results_leading_out_is_refused(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    root = tmp_path / "study"
    (root / "results" / "st").mkdir(parents=True)
    os.symlink(outside, root / "results" / "st" / "S1")
    with pytest.raises(InputError, match="a symbolic link leads it to .*outside"):
        check_inside_study(["results/st/S1/qr/rank.tsv"], root)
    # the results folder itself may be a link (a scratch disk): the study's own choice
    scratch = tmp_path / "scratch"
    (scratch / "st").mkdir(parents=True)
    other = tmp_path / "study2"
    other.mkdir()
    os.symlink(scratch, other / "results")
    check_inside_study(["results/st/x.tsv"], other)
    (root / "results" / "st2").symlink_to(scratch / "st")
    check_inside_study(["results/st2/S1/x.tsv"], root)


JOB = textwrap.dedent('''
    import sys
    from pathlib import Path
    from facemotion.study.adapter import run_step

    class Names(dict):
        __getattr__ = dict.__getitem__

    class Files(list):  # Snakemake's namedlist: a list of the paths, named
        out = sys.argv[1]

    class Snakemake:  # what Snakemake's script preamble makes, by its name and package
        rule = "simulate_lip_talker"
        input, params = Names(), Names()
        wildcards = Names(lip_subject="x")
        output = Files([sys.argv[1]])
        log = ["results/st/logs/x.log"]
    Snakemake.__module__ = "snakemake.iocontainers"

    def main(sm, log, prov):
        Path(sm.output.out).write_text("written")

    run_step(Snakemake(), main)
''')


def test_a_job_refuses_to_write_outside_before_writing(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    root = tmp_path / "study"
    (root / "results" / "st" / "lips").mkdir(parents=True)
    os.symlink(outside, root / "results" / "st" / "lips" / "x")
    proc = subprocess.run([sys.executable, "-c", JOB, "results/st/lips/x/tracks.trc"],
                          cwd=root, capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [
        f"facemotion: simulate_lip_talker x: output path results/st/lips/x/tracks.trc: a "
        f"symbolic link leads it to {outside}/tracks.trc, outside {root}/results/st; "
        "nothing was written"]
    assert list(outside.iterdir()) == [] and not (root / "results" / "st" / "logs").exists()
    (root / "results" / "st" / "lips" / "y").mkdir()  # as Snakemake makes it
    ok = subprocess.run([sys.executable, "-c", JOB, "results/st/lips/y/tracks.trc"],
                        cwd=root, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert (root / "results" / "st" / "lips" / "y" / "tracks.trc").read_text() == "written"
