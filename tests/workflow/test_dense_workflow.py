"""The dense study (config/dense.yaml) plans with the shared data (the dense talker's design,
its TRC files, the GRID all-landmark datasets), and a k_max beyond a dataset's markers is
refused at parse time (one line, never clamped)."""

import subprocess
import sys

import pytest
from helpers import REPO, SHARED_DATA

SHARED = SHARED_DATA
pytestmark = pytest.mark.workflow


def dry_run(tmp_path, config, extra=None):
    configs = [str(REPO / "config" / config)]
    if extra:
        (tmp_path / "extra.yaml").write_text(extra)
        configs.append(str(tmp_path / "extra.yaml"))
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "--directory",
           str(tmp_path), "--cores", "1", "-n", "--configfile", *configs,
           "--config", f"shared_data={SHARED}"]
    return subprocess.run(cmd, capture_output=True, text=True)


def test_dense_study_plans_the_talker(tmp_path):
    proc = dry_run(tmp_path, "dense.yaml")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert "simulate_subject" in out and "rank_markers" in out


def test_k_max_beyond_a_dataset_is_refused(tmp_path):
    proc = dry_run(tmp_path, "dense.yaml", "qr:\n  k_max: 44\n")
    assert proc.returncode != 0
    err = (proc.stdout + proc.stderr).strip().splitlines()
    assert any("setting qr.k_max: 44 must be fewer than the markers of dataset grid_t1" in line
               for line in err), err[-5:]
