"""Paths given on the command line, study names, and a default study that parses anywhere.

The unit tests build directory layouts in tmp_path; the workflow tests run `snakemake -n` and
`snakemake --lint` (parse only, a few seconds each).
"""

import os
import shutil
import subprocess
import sys

import pytest
from helpers import REPO, SHARED_DATA

from facemotion.errors import InputError
from facemotion.study.invocation import ENV, invocation_dir, resolve_path, same_study_command
from facemotion.study.summary import study_name

SNAKEMAKE = [sys.executable, "-m", "snakemake"]


# ---- where the user typed the command ----

def test_without_directory_the_invocation_dir_is_the_working_dir(tmp_path):
    assert invocation_dir("/elsewhere", None, cwd=tmp_path, env={}) == tmp_path


def test_relative_directory_checks_snakemakes_record(tmp_path):
    inv, wd = tmp_path / "inv", tmp_path / "inv" / "a" / "wd"
    wd.mkdir(parents=True)
    assert invocation_dir(inv, "a/wd", cwd=wd, env={"PWD": "/stale"}) == inv
    # a record that does not lead to the working directory is not used; PWD is, if it does
    assert invocation_dir(tmp_path, "a/wd", cwd=wd, env={"PWD": str(inv)}) == inv
    assert invocation_dir(tmp_path, "a/wd", cwd=wd, env={"PWD": "/stale"}) is None


def test_a_submitted_jobs_snakemake_uses_the_main_process_record(tmp_path):
    inv, wd = tmp_path / "inv", tmp_path / "wd"
    inv.mkdir()
    wd.mkdir()
    # a cluster job starts in the working directory, with --directory as the main process had it
    env = {ENV: f"{inv}\n{wd}"}
    assert invocation_dir(wd, str(wd), cwd=wd, env=env) == inv
    # the record of another working directory is ignored
    env = {ENV: f"{inv}\n{tmp_path}"}
    assert invocation_dir(wd, str(wd), cwd=wd, env=env) == wd


def test_command_line_path_is_resolved_against_the_invocation_dir(tmp_path, monkeypatch):
    inv, wd = tmp_path / "inv", tmp_path / "wd"
    (inv / "sheets").mkdir(parents=True)
    wd.mkdir()
    (inv / "sheets" / "lab.tsv").write_text("x")
    (wd / "sheets").mkdir()
    (wd / "sheets" / "lab.tsv").write_text("the wrong one")
    monkeypatch.chdir(wd)
    got = resolve_path("sheets/lab.tsv", "subjects", from_command_line=True, inv=inv,
                       repo=REPO, what="subject sheet")
    assert got == inv / "sheets" / "lab.tsv"
    # from a config file: the working directory
    got = resolve_path("sheets/lab.tsv", "subjects", from_command_line=False, inv=inv,
                       repo=REPO, what="subject sheet")
    assert got == wd / "sheets" / "lab.tsv"


def test_missing_path_says_where_it_looked(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as err:
        resolve_path("nope.tsv", "subjects", from_command_line=True, inv=tmp_path / "inv",
                     repo=REPO, what="subject sheet")
    msg = str(err.value)
    assert "setting subjects" in msg and str(tmp_path / "inv" / "nope.tsv") in msg
    assert "\n" not in msg
    with pytest.raises(InputError, match="give an absolute path"):
        resolve_path("nope.tsv", "subjects", from_command_line=True, inv=None, repo=REPO,
                     what="subject sheet")
    with pytest.raises(InputError) as err:
        resolve_path("nope.tsv", "subjects", from_command_line=False, inv=None, repo=REPO,
                     what="subject sheet")
    assert str(tmp_path / "nope.tsv") in str(err.value) and str(REPO / "nope.tsv") in str(
        err.value)


def test_study_names():
    assert study_name("mine", ["/x/real.yaml"], "s.tsv", True) == "mine"
    assert study_name(None, ["/x/smoke.yaml", "/y/real.yaml"], "s.tsv", False) == "real"
    assert study_name(None, [], "/x/lab_2024.tsv", True) == "lab_2024"
    assert study_name(None, [], "config/subjects.tsv", False) == "paper"
    with pytest.raises(InputError, match="setting study"):
        study_name(None, [], "/x/my sheet.tsv", True)


def test_report_hint_keeps_the_options_that_name_the_study():
    argv = ["/v/bin/snakemake", "--cores", "2", "-s", "/r/Snakefile", "--directory", "d",
            "--configfile", "a.yaml", "b.yaml", "--config", "study=x", "-n"]
    assert same_study_command(argv, "--report", "results/x/report.html") == (
        "snakemake -s /r/Snakefile --directory d --configfile a.yaml b.yaml --config study=x "
        "--report results/x/report.html")


def test_report_hint_names_the_snakemake_that_ran(tmp_path, monkeypatch):
    """`make study` runs .venv/bin/snakemake, which is not on the PATH: the hint gives its
    path relative to where the user is; a snakemake found on the PATH is just `snakemake`."""
    exe = tmp_path / ".venv" / "bin" / "snakemake"
    exe.parent.mkdir(parents=True)
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert same_study_command([str(exe), "--cores", "2"], "--report", "r.html") == (
        ".venv/bin/snakemake --report r.html")
    monkeypatch.setenv("PATH", str(exe.parent))
    assert same_study_command([str(exe)], "--report", "r.html") == "snakemake --report r.html"
    assert same_study_command(["/x/__main__.py"], "-n") == "snakemake -n"


# ---- through snakemake (parse only) ----

def _snakemake(*args, cwd, env=None):
    env = dict(os.environ, **(env or {}))
    env.pop(ENV, None)
    return subprocess.run(SNAKEMAKE + list(args), cwd=cwd, capture_output=True, text=True,
                          env=env)


@pytest.mark.workflow
def test_relative_sheet_is_read_from_where_snakemake_was_started(tmp_path):
    inv = tmp_path / "inv"
    (inv / "sheets").mkdir(parents=True)
    shutil.copy(REPO / "config" / "smoke_subjects.tsv", inv / "sheets" / "lab.tsv")
    # PWD is stale on purpose (as when a program, not a shell, starts snakemake)
    proc = _snakemake("-s", str(REPO / "Snakefile"), "--directory", "wd", "-n", "--config",
                      "subjects=sheets/lab.tsv", cwd=inv, env={"PWD": "/nonexistent"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "all: study 'lab' complete" in proc.stdout  # the study is named after the sheet

    proc = _snakemake("-s", str(REPO / "Snakefile"), "--directory", "wd2", "--cores", "1",
                      "--config", "subjects=sheets/nope.tsv", cwd=inv)
    assert proc.returncode == 1
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("facemotion: setting subjects:"), last
    assert str(inv / "sheets" / "nope.tsv") in last
    # a failed parse leaves no .snakemake/ (nor results) behind
    assert not (inv / "wd2" / ".snakemake").exists()
    assert not (inv / "wd2" / "results").exists()


@pytest.mark.workflow
def test_default_study_lints_and_dry_runs_without_the_shared_data(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    for args in (["--lint"], ["-n"]):
        proc = _snakemake("-s", str(REPO / "Snakefile"), "--directory", str(tmp_path / "wd"),
                          *args, "--config", f"shared_data={empty}", cwd=tmp_path)
        out = proc.stdout + proc.stderr
        assert proc.returncode == 0, out[-3000:]
        skipped = [line for line in out.splitlines() if "skipped" in line]
        assert len(skipped) == 1 and "grid_talker" in skipped[0], skipped
        assert str(empty / "grid") in skipped[0]
    assert "fit_lip_model                 1" in out  # the virtual lip talker still runs


@pytest.mark.workflow
def test_fresh_clone_without_shared_folder_dry_runs(tmp_path):
    """The repository's files alone (no ../shared beside them): the default study dry-runs."""
    clone = tmp_path / "clone"
    shutil.copytree(REPO, clone, ignore=shutil.ignore_patterns(
        ".venv", ".git", ".snakemake", "results", "__pycache__", "*.egg-info"))
    proc = _snakemake("-n", cwd=clone)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "skipped lip subject grid_talker" in out
    assert not (tmp_path / "shared").exists()


@pytest.mark.workflow
@pytest.mark.parametrize("name", ["config", "real", "dense", "smoke", "talkers"])
def test_every_shipped_config_dry_runs_with_the_shared_data(tmp_path, name):
    """Each config file of the repository parses and plans (its paths resolve, e.g. the GRID
    datasets' face mesh in the shared data)."""
    shared = SHARED_DATA
    assert shared.is_dir(), f"no shared data at {shared} (set FACEMOTION_SHARED_DATA)"
    proc = _snakemake("-s", str(REPO / "Snakefile"), "--directory", str(tmp_path / "wd"), "-n",
                      "--configfile", str(REPO / "config" / f"{name}.yaml"),
                      "--config", f"shared_data={shared}", cwd=tmp_path)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "Job stats" in out


def test_benchmark_sampling_interval_is_set_in_this_snakemake():
    """If Snakemake renames its sampling interval, this fails (the study would sample twice a
    second again, about 4 s of CPU)."""
    import snakemake.benchmark as bench

    from facemotion.study.invocation import sample_benchmarks_every

    before = bench.BENCHMARK_INTERVAL_SHORT
    try:
        assert sample_benchmarks_every(5.0)
        assert bench.BENCHMARK_INTERVAL_SHORT == 5.0
    finally:
        bench.BENCHMARK_INTERVAL_SHORT = before
