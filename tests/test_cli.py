"""The `facemotion` command line: help, one-line errors, info, rank against the workflow."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from helpers import REPO

from facemotion.cli import cli, main
from facemotion.io.recording import Recording
from facemotion.io.wide_csv import write_csv

HEAD = ["ForeHead_M", "ForeHead_L", "ForeHead_R", "NoseTop", "Leye_Inside", "Reye_Inside"]


def run(*args):
    """The installed console script, as a user runs it."""
    exe = Path(sys.executable).with_name("facemotion")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)


def test_help_explains_every_option():
    for cmd in ([], ["info"], ["rank"], ["study"]):
        res = CliRunner().invoke(cli, [*cmd, "--help"])
        assert res.exit_code == 0, res.output
        command = cli.commands[cmd[0]] if cmd else cli
        for p in command.params:
            if p.param_type_name == "option" and p.name not in ("help", "version"):
                option = next(o for o in p.opts if o.startswith("--"))
                assert option in res.output
                assert p.help and len(p.help) > 20, f"{cmd} {option} has no real help"


def test_errors_are_one_line_with_a_non_zero_status(tmp_path):
    res = run("rank", tmp_path / "missing.c3d", "--head", "A,B,C")
    assert res.returncode == 1
    assert res.stderr.count("\n") == 1 and "missing.c3d: file not found" in res.stderr
    res = run("rank", "--head", "A,B,C")  # no file
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert "Missing argument" in res.stderr and "facemotion rank --help" in res.stderr
    res = run("rank", "x.c3d", "--tolerance", "abc")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "'abc'" in res.stderr
    assert run("--version").stdout.startswith("facemotion, version")


def write_take(path, seed=0):
    rng = np.random.default_rng(seed)
    F, n = 120, 6
    pts = np.cumsum(rng.normal(size=(F, n, 3)), axis=0) + np.arange(n)[None, :, None] * 30
    pts[10:13, 2] = np.nan     # one gap of 3 frames in C
    pts[50:52, 2] = np.nan     # and one of 2
    pts[70:90, 4] = np.nan     # 20 frames in E
    rec = Recording(list("ABCDEF"), pts, 100.0)
    write_csv(path, rec)
    return rec


def test_info_counts_the_gaps(tmp_path):
    write_take(tmp_path / "t.csv")
    res = run("info", tmp_path / "t.csv")
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "markers: 6" in out and "rate: 100 Hz" in out and "frames: 120 (1.200 s)" in out
    assert "missing samples: 25 of 720 (3.47%), 3 gap(s) in 2 marker(s)" in out
    row = next(line.split() for line in out.splitlines() if line.split()[:1] == ["C"])
    assert row == ["C", "5", "2", "3"]


def test_study_without_snakemake_is_a_one_line_error(monkeypatch, capsys):
    import facemotion.cli as mod

    monkeypatch.setattr(mod.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(SystemExit) as e:
        main(["study", "-n"])
    assert e.value.code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'facemotion[workflow]'" in err


def test_study_passes_through_to_snakemake(tmp_path):
    res = subprocess.run([str(Path(sys.executable).with_name("facemotion")), "study",
                          "--configfile", str(REPO / "config" / "smoke.yaml"),
                          "--directory", str(tmp_path), "-n", "--quiet", "rules"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "rank_markers" in res.stdout + res.stderr


def parse_rank(stdout):
    lines = stdout.splitlines()
    first = next(line for line in lines if line.startswith("first pivots: "))
    start = next(i for i, line in enumerate(lines) if line.split()[:2] == ["order", "marker"])
    rows = []
    for line in lines[start + 1:]:
        if not line.strip():
            break
        rows.append(line.split())
    table = pd.DataFrame(rows, columns=lines[start].split())
    return first[len("first pivots: "):].split(", "), table


@pytest.mark.workflow
def test_rank_prints_the_workflows_first_pivots_on_animface(tmp_path):
    from helpers import require_shared_data as shared_data

    root = shared_data()
    takes = sorted((root / "animface").glob("animface_*.c3d"))  # the real sheet's order
    assert [t.name for t in takes] == ["animface_eyebrows.c3d", "animface_jaw.c3d"]
    head = ",".join(HEAD)
    # the workflow: config/real.yaml's dataset "animface" (both takes), and the jaw take alone
    # (no held-out take: held-out takes are loaded too and share the head reference)
    sheet = pd.read_csv(REPO / "config" / "real_subjects.tsv", sep="\t", dtype=str,
                        keep_default_na=False)
    sheet[sheet["subject"] == "animface"].to_csv(tmp_path / "subjects.tsv", sep="\t",
                                                 index=False)
    (tmp_path / "config.yaml").write_text(
        f"subjects: {tmp_path / 'subjects.tsv'}\nshared_data: {root}\ndefault_datasets: false\n"
        "datasets:\n  animface: {subject: animface, train: '1-2'}\n"
        "  animface_jaw: {subject: animface, train: '2', heldout: []}\n"
        "lips: {subjects: {}}\n")
    # the study is named after the config file: results/config/
    targets = [f"results/config/{d}/qr/r_values.tsv" for d in ("animface", "animface_jaw")]
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", *targets, "-s", str(REPO / "Snakefile"),
         "--directory", str(tmp_path), "--cores", "2", "--configfile",
         str(tmp_path / "config.yaml")], capture_output=True, text=True,
        env=dict(os.environ, PYTHONHASHSEED="0"))
    assert proc.returncode == 0, proc.stderr[-4000:]
    for target, files in zip(targets, [takes, takes[1:]], strict=True):
        workflow = pd.read_csv(tmp_path / target, sep="\t")
        res = run("rank", *files, "--head", head, "--exclude", head)
        assert res.returncode == 0, res.stderr
        first, table = parse_rank(res.stdout)
        assert first == workflow["marker"].tolist()[:10]
        assert table["marker"].tolist() == workflow["marker"].tolist()
        np.testing.assert_allclose(table["r"].astype(float), workflow["r"], rtol=1e-5)
        assert not set(HEAD) & set(table["marker"])
        # streamed (--max-gib): the takes read in blocks, the same answer, the same lines
        streamed = run("rank", *files, "--head", head, "--exclude", head, "--max-gib", "0.1")
        assert streamed.returncode == 0, streamed.stderr
        assert streamed.stdout == res.stdout
    res = run("rank", *takes, "--head", head, "--max-gib", "0")
    assert res.returncode == 2 and "--max-gib" in res.stderr and res.stderr.count("\n") == 1


def test_rank_says_what_the_loading_filled_and_names_a_repeated_head_marker(tmp_path):
    """A non-finite sample is a missing sample: filled, and said on stderr with its marker
    (the ranking equals the clean take's, as the one sample is interpolated); a head marker
    given twice is blamed on the option, not on the file."""
    import ezc3d
    from helpers import require_shared_data as shared_data

    jaw = shared_data() / "animface" / "animface_jaw.c3d"
    c = ezc3d.c3d(str(jaw))
    labels = list(c["parameters"]["POINT"]["LABELS"]["value"])
    pts = c["data"]["points"]
    pts[0, labels.index("Chin"), 100] = np.inf
    c["data"]["points"] = pts
    del c["data"]["meta_points"]
    bad = tmp_path / "jaw_inf.c3d"
    c.write(str(bad))
    head = ",".join(HEAD)
    clean = run("rank", jaw, "--head", head, "--exclude", head)
    res = run("rank", bad, "--head", head, "--exclude", head)
    assert clean.returncode == 0 and res.returncode == 0, res.stderr
    assert "missing sample" not in clean.stderr
    assert res.stderr.startswith("facemotion: 1 missing sample(s) filled: Chin (1)")
    assert parse_rank(res.stdout)[0] == parse_rank(clean.stdout)[0]
    res = run("rank", jaw, "--head", "ForeHead_M,ForeHead_M,NoseTop")
    assert res.returncode == 1 and res.stderr.count("\n") == 1
    assert "head_markers (the arguments): marker(s) ForeHead_M listed twice" in res.stderr
    res = run("rank", jaw, "--head", "ForeHead_M,Nope,NoseTop")
    assert res.returncode == 1
    assert "marker 'Nope' (named in head_markers of the arguments) is not" in res.stderr
