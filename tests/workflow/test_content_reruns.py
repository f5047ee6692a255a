"""Reruns follow content, and outputs do not depend on the folder a study runs in.

A user's sheet beside their data, outside the study folder: takes replaced by other content
with an older or unchanged modification time (``cp -p``, ``touch -d``, ``rsync -t``) rerun the
loading and what depends on it, and the dry run says why; putting the original back leaves
nothing to do. The same study run in two folders writes the same bytes, sidecars included."""

from __future__ import annotations

import filecmp
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import REPO

pytestmark = pytest.mark.workflow
HEAD = "H1,H2,H3,H4,H5,H6"
OLD = 946684800  # 2000-01-01: older than any output


def snakemake(workdir, *args, sheet, more=""):
    extra = Path(workdir) / "extra.yaml"
    extra.write_text(f"subjects: {sheet}\ndefault_datasets: true\nsweeps: {{}}\n"
                     f"virtual_talkers: {{n_talkers: 0}}\n{more}")
    cmd = [sys.executable, "-m", "snakemake", *args, "-s", str(REPO / "Snakefile"),
           "--directory", str(workdir), "--cores", "2", "--configfile",
           str(REPO / "config" / "smoke.yaml"), str(extra)]
    proc = subprocess.run(cmd, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONHASHSEED="0"))
    assert proc.returncode == 0, f"{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}"
    return proc.stdout + proc.stderr


TARGETS = [f"results/smoke/lab/{rel}" for rel in
           ("data/displacements.npz", "data/sentences.tsv", "qr/rank.tsv", "qr/r_values.tsv")]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    sim = tmp_path_factory.mktemp("sim")
    cmd = [sys.executable, "-m", "snakemake", "results/smoke/virtual/S1", "-s",
           str(REPO / "Snakefile"), "--directory", str(sim), "--cores", "2",
           "--configfile", str(REPO / "config" / "smoke.yaml")]
    subprocess.run(cmd, check=True, capture_output=True)
    data = tmp_path_factory.mktemp("data")
    (data / "takes").mkdir()
    for f in sorted((sim / "results" / "smoke" / "virtual" / "S1").glob("S1_s*.c3d")):
        shutil.copy2(f, data / "takes" / f.name.replace("S1_s", "take"))
    sheet = data / "subjects.tsv"
    sheet.write_text(
        "subject\trecordings\tformat\thead_markers\texclude_markers\tcopy_markers\n"
        f"lab\ttakes/take*.c3d\tc3d\t{HEAD}\t{HEAD}\t13=11\n")
    runs = [tmp_path_factory.mktemp("studyA"), tmp_path_factory.mktemp("elsewhere") / "B"]
    for work in runs:  # the whole study, every output
        work.mkdir(exist_ok=True)
        snakemake(work, sheet=sheet)
    return data, sheet, runs


def _dry(study):
    data, sheet, runs = study
    return snakemake(runs[0], "-n", *TARGETS, sheet=sheet)


def _cp_p(src, dst):
    subprocess.run(["cp", "-p", str(src), str(dst)], check=True)


def _touch_d(src, dst):
    dst.write_bytes(src.read_bytes())
    subprocess.run(["touch", "-d", "2000-01-01 00:00:00", str(dst)], check=True)


def _rsync_t(src, dst):
    """What ``rsync -t`` does: a temporary file beside the target, the source's modification
    time set on it, renamed onto the target (a new inode)."""
    tmp = dst.with_name(f".{dst.name}.rsync")
    tmp.write_bytes(src.read_bytes())
    st = os.stat(src)
    os.utime(tmp, ns=(st.st_atime_ns, st.st_mtime_ns))
    os.replace(tmp, dst)


@pytest.mark.parametrize("replace", [_cp_p, _touch_d, _rsync_t], ids=["cp-p", "touch-d",
                                                                       "rsync-t"])
def test_a_replaced_take_reruns_loading_and_its_dependants(study, replace, tmp_path):
    data, _, _ = study
    take = data / "takes" / "take01.c3d"
    original = tmp_path / "take01.c3d"
    shutil.copy2(take, original)
    other = tmp_path / "other.c3d"
    shutil.copy2(data / "takes" / "take02.c3d", other)
    os.utime(other, (OLD, OLD))  # an older take: mtime alone would see nothing new
    assert "Nothing to be done" in _dry(study)
    try:
        replace(other, take)
        assert os.stat(take).st_mtime < os.stat(study[2][0] / TARGETS[0]).st_mtime
        out = _dry(study)
        assert "load_dataset" in out and "rank_markers" in out
        assert "Params have changed since last execution" in out
        assert "{sheet}/takes/take01.c3d sha256:" in out  # the reason names the file
    finally:
        _cp_p(original, take)  # the original back (its own, older mtime)
    assert "Nothing to be done" in _dry(study)


def test_same_study_in_two_folders_gives_the_same_bytes(study):
    """Every output of the whole study (tables, figures, the animation, the summary, the
    manifest) and every sidecar, not only the dataset's."""
    _, _, (a, b) = study
    base_a, base_b = a / "results" / "smoke", b / "results" / "smoke"
    files = sorted(p.relative_to(base_a) for p in base_a.rglob("*")
                   if p.is_file() and not {"logs", "benchmarks", ".cache"} & set(p.parts))
    assert {"lab/data/sentences.meta.json", "manifest.tsv", "summary.txt",
            "tables/rank_summary.tsv"} <= {str(f) for f in files}
    assert sorted(p.relative_to(base_b) for p in base_b.rglob("*") if p.is_file() and not
                  {"logs", "benchmarks", ".cache"} & set(p.parts)) == files
    differ = [str(f) for f in files if not filecmp.cmp(base_a / f, base_b / f, shallow=False)]
    assert differ == []
    sentences = (base_a / "lab" / "data" / "sentences.tsv").read_text()
    assert "{sheet}/takes/take01.c3d" in sentences and str(a) not in sentences


def test_mostly_filled_pivots_are_named_and_can_be_left_out(study, tmp_path):
    """Marker 13 of the virtual talker is recorded in each sentence's first frame only and
    copied from 11 (copy_markers), so almost all of it is made up: with every pivot checked it
    is named in rank.tsv, the log and the figure; qr.max_filled_fraction leaves it out."""
    import pandas as pd

    _, sheet, _ = study
    snakemake(tmp_path, *TARGETS, sheet=sheet,
              more="qr: {replicates: 20, optimality_k_max: 3, flag_pivots: 57}\n")
    base = tmp_path / "results" / "smoke" / "lab"
    r = pd.read_csv(base / "qr" / "r_values.tsv", sep="\t", dtype={"marker": str})
    assert list(r.columns[-2:]) == ["filled_fraction", "outlier_fraction"]
    filled = dict(zip(r["marker"], r["filled_fraction"], strict=True))
    assert filled["13"] > 0.9 and filled["11"] == 0.0
    rank = pd.read_csv(base / "qr" / "rank.tsv", sep="\t", keep_default_na=False)
    order13 = int(r.loc[r["marker"] == "13", "order"].iloc[0])
    named = f"pivot {order13} 13 {100 * filled['13']:.0f} % filled"
    assert set(rank["mostly_filled_pivots"]) == {named}
    log = (tmp_path / "results" / "smoke" / "logs" / "rank_markers" / "lab.log").read_text()
    assert named in log
    # left out of A with qr.max_filled_fraction
    snakemake(tmp_path, *TARGETS, sheet=sheet,
              more="qr: {replicates: 20, optimality_k_max: 3, max_filled_fraction: 0.9}\n")
    r = pd.read_csv(base / "qr" / "r_values.tsv", sep="\t", dtype={"marker": str})
    assert "13" not in set(r["marker"]) and len(r) == 56
    rank = pd.read_csv(base / "qr" / "rank.tsv", sep="\t", keep_default_na=False, dtype=str)
    assert set(rank["left_out_filled"]) == {"13"} and set(rank["mostly_filled_pivots"]) == {""}
    gaps = pd.read_csv(base / "data" / "gap_report.tsv", sep="\t", dtype={"marker": str})
    assert gaps.loc[gaps["marker"] == "13", "fill_method"].tolist() == ["left out"]
