"""The command line in scripts: --json / --tsv on stdout, exit codes, --version without the
numerical stack, help on a bare `facemotion`, a progress bar only on a terminal."""

import json
import subprocess
import sys

import pytest

from facemotion.io.c3d import write_c3d
from facemotion.virtual.talker import simulate_subject

HEAD = "H1,H2,H3,H4,H5,H6"


def run(*args, module="facemotion._entry", **kw):
    return subprocess.run([sys.executable, "-m", module, *map(str, args)],
                          capture_output=True, text=True, check=False, **kw)


@pytest.fixture(scope="module")
def takes(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    s = simulate_subject("S2a", seed=6, n_sentences=3, occlusions=False)
    paths = []
    for r in s.recordings:
        paths.append(out / f"{r.source}.c3d")
        write_c3d(paths[-1], r)
    return paths


def test_version_does_not_import_the_numerical_stack():
    code = ("import sys; from facemotion._entry import main\n"
            "try:\n    main(['--version'])\nexcept SystemExit as e:\n"
            "    print([m for m in ('numpy', 'pandas', 'scipy', 'click') if m in sys.modules],"
            " e.code)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("facemotion, version ")
    assert lines[1] == "[] 0"


def test_bare_command_prints_help_and_exits_0():
    proc = run()
    assert proc.returncode == 0
    assert "Usage: facemotion" in proc.stdout and "Exit status" in proc.stdout


def test_rank_json_pipes_into_json_tool(takes):
    rank = run("rank", *takes, "--head", HEAD, "--exclude", HEAD, "--json")
    assert rank.returncode == 0, rank.stderr
    tool = subprocess.run([sys.executable, "-m", "json.tool"], input=rank.stdout,
                          capture_output=True, text=True, check=False)
    assert tool.returncode == 0
    answer = json.loads(rank.stdout)
    assert answer["markers"] == 57 and len(answer["first_pivots"]) == 10
    assert [p["order"] for p in answer["pivots"]] == list(range(1, 58))
    assert "\r" not in rank.stderr            # no progress bar when stderr is not a terminal
    tsv = run("rank", *takes, "--head", HEAD, "--exclude", HEAD, "--tsv")
    lines = tsv.stdout.splitlines()
    assert lines[0].split("\t")[:3] == ["order", "marker", "r"] and len(lines) == 58
    assert lines[1].split("\t")[1] == answer["first_pivots"][0]


def test_info_json_and_tsv(takes):
    answer = json.loads(run("info", takes[0], "--json").stdout)
    assert answer["markers"] == 63 and answer["rate_hz"] == 120.0
    assert answer["per_marker"][0]["marker"] == "1"
    tsv = run("info", takes[0], "--tsv").stdout.splitlines()
    assert tsv[0] == "marker\tmissing_frames\tn_gaps\tlongest_gap_frames" and len(tsv) == 64


def test_exit_codes(takes, tmp_path):
    missing = run("info", tmp_path / "absent.c3d")
    assert missing.returncode == 1
    assert missing.stderr.strip() == f"facemotion: error: {tmp_path / 'absent.c3d'}: file not found"
    assert run("info").returncode == 2                       # a wrong command line
    assert run("rank", takes[0], "--first", "0").returncode == 2


def test_progress_bar_only_on_a_terminal(takes, capsys):
    from facemotion.ingest.loading import progress_bar

    assert progress_bar(3, "reading", show=False) is None
    bar = progress_bar(3, "reading", show=True)
    assert bar is not None and bar.disable           # pytest's stderr is not a terminal
    bar.close()
