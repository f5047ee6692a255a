"""A one-take-per-block study through the workflow: the virtual sentences of S1 concatenated into
two long takes (with other motion between the sentences), cut by C3D events and by a TextGrid
tier, give the same displacement matrix A (bit-identical) and the same marker ranking as the
same sentences in one file each."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import ezc3d
import numpy as np
import pandas as pd
import pytest
from helpers import REPO
from praatio import textgrid
from praatio.utilities.constants import Interval

from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording

pytestmark = pytest.mark.workflow
HEAD = "H1,H2,H3,H4,H5,H6"
DATASETS = ("split", "events", "textgrid")


def run_snakemake(workdir, *targets, extra_config=""):
    """The smoke config (plus ``extra_config``), building only ``targets``."""
    configs = [str(REPO / "config" / "smoke.yaml")]
    if extra_config:
        (Path(workdir) / "extra.yaml").write_text(extra_config)
        configs.append(str(Path(workdir) / "extra.yaml"))
    cmd = [sys.executable, "-m", "snakemake", *targets, "-s", str(REPO / "Snakefile"),
           "--directory", str(workdir), "--cores", "2", "--configfile", *configs]
    proc = subprocess.run(cmd, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONHASHSEED="0"))
    if proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n"
                             f"{proc.stderr[-5000:]}")
    return proc


def make_blocks(sentence_files, take_dir, blocks):
    """Concatenate sentences into takes; 9 frames of another pose before each sentence;
    EVENT pairs 'Sentence Start'/'Sentence End' and a TextGrid tier 'sentence' on the bounds."""
    recs = [read_c3d(f) for f in sentence_files]
    rate = recs[0].rate
    for block, members in blocks.items():
        parts, entries, f = [], [], 0
        for k in members:
            parts.append(recs[k].points[:9] + 25.0)
            f += 9
            parts.append(recs[k].points)
            entries.append((f, f + recs[k].n_frames, Path(sentence_files[k]).stem))
            f += recs[k].n_frames
        take = take_dir / f"{block}.c3d"
        write_c3d(take, Recording(recs[0].labels, np.concatenate(parts), rate))
        c = ezc3d.c3d(str(take))
        for a, b, _ in entries:
            c.add_event(time=[0, a / rate], context="General", label="Sentence Start")
            c.add_event(time=[0, b / rate], context="General", label="Sentence End")
        c.add_event(time=[0, 2 / rate], context="General", label="Foot Strike")
        c.write(str(take))
        tg = textgrid.Textgrid()
        tg.addTier(textgrid.IntervalTier(
            "sentence", [Interval(a / rate, b / rate, name) for a, b, name in entries],
            0, f / rate))
        tg.save(str(take_dir / f"{block}.TextGrid"), format="long_textgrid",
                includeBlankSpaces=True)


@pytest.fixture(scope="module")
def block_study(tmp_path_factory):
    sim = tmp_path_factory.mktemp("sim")
    run_snakemake(sim, "results/smoke/virtual/S1")
    sentence_files = sorted((sim / "results" / "smoke" / "virtual" / "S1").glob("S1_s*.c3d"))
    assert len(sentence_files) == 6
    data = tmp_path_factory.mktemp("lab")
    (data / "takes").mkdir()
    make_blocks(sentence_files, data / "takes", {"block1": [0, 1, 2], "block2": [3, 4, 5]})
    sheet = data / "subjects.tsv"
    sheet.write_text(
        # the virtual S1 loses marker 13 after each sentence's first frame: copy 11 into it
        "subject\trecordings\tformat\thead_markers\texclude_markers\tsegments\tcopy_markers\n"
        f"split\t{sim}/results/smoke/virtual/S1/S1_s*.c3d\tc3d\t{HEAD}\t{HEAD}\t\t13=11\n"
        f"events\ttakes/block*.c3d\tc3d\t{HEAD}\t{HEAD}\tevents:Sentence Start,Sentence End"
        "\t13=11\n"
        f"textgrid\ttakes/block*.c3d\tc3d\t{HEAD}\t{HEAD}\t"
        "textgrid:takes/{stem}.TextGrid#sentence\t13=11\n")
    work = tmp_path_factory.mktemp("run")
    targets = [f"results/smoke/{d}/{rel}" for d in DATASETS
               for rel in ("data/displacements.npz", "qr/rank.tsv", "qr/r_values.tsv",
                           "eval/error_curve.tsv", "stream/r_values.tsv",
                           "stream/error_curve.tsv")]
    run_snakemake(work, *targets,
                  extra_config=f"subjects: {sheet}\ndefault_datasets: true\nsweeps: {{}}\n")
    return work / "results" / "smoke"


def test_cut_takes_give_the_same_A_as_split_files(block_study):
    npz = {d: np.load(block_study / d / "data" / "displacements.npz") for d in DATASETS}
    for d in ("events", "textgrid"):
        for key in ("A", "row_sentence", "row_frame", "fill_mask", "labels"):
            assert np.array_equal(npz[d][key], npz["split"][key]), (d, key)
    assert npz["split"]["A"].shape[1] == 57


def test_sentences_table_names_the_cut_sentences(block_study):
    split = pd.read_csv(block_study / "split" / "data" / "sentences.tsv", sep="\t")
    names = [f"S1_s{k:02d}" for k in range(1, 7)]
    assert list(split["sentence"]) == names
    tg = pd.read_csv(block_study / "textgrid" / "data" / "sentences.tsv", sep="\t")
    assert list(tg["sentence"]) == names  # named by the tier's text
    assert list(tg["frames"]) == list(split["frames"])
    assert list(tg["role"]) == list(split["role"]) == ["train"] * 4 + ["heldout"] * 2
    assert [Path(f).name for f in tg["file"]] == ["block1.c3d"] * 3 + ["block2.c3d"] * 3
    ev = pd.read_csv(block_study / "events" / "data" / "sentences.tsv", sep="\t")
    assert list(ev["sentence"]) == [f"block{b}_{k:02d}" for b in (1, 2) for k in (1, 2, 3)]
    # the first sentence of each block starts after the 9 frames of another pose
    rate = split["frames"].iloc[0] / split["duration_s"].iloc[0]
    assert np.allclose(ev["start_s"].iloc[[0, 3]], 9 / rate)


def test_cut_takes_give_the_same_ranking(block_study):
    rank = {d: pd.read_csv(block_study / d / "qr" / "rank.tsv", sep="\t") for d in DATASETS}
    for d in ("events", "textgrid"):
        assert rank[d].equals(rank["split"])


def test_the_stream_target_reads_each_take_once_for_its_sentences(block_study):
    """The scattered streamed load (target `stream`): one job per take (block1, block2; each
    holds training and held-out sentences), its r values and held-out error curve the
    whole-take rules' (to the digits the tables print), for the takes cut by events and by the
    TextGrid as for the sentences in one file each."""
    for d in DATASETS:
        takes = sorted(p.name for p in (block_study / d / "stream" / "takes").glob("t*.gram.npz"))
        assert takes == (["t001.gram.npz", "t002.gram.npz"] if d != "split"
                         else [f"t{k:03d}.gram.npz" for k in range(1, 7)])
        for streamed, whole, key in (("stream/r_values.tsv", "qr/r_values.tsv", "marker"),
                                     ("stream/error_curve.tsv", "eval/error_curve.tsv",
                                      "main_markers")):
            a = pd.read_csv(block_study / d / streamed, sep="\t", dtype={key: str})
            b = pd.read_csv(block_study / "split" / whole, sep="\t", dtype={key: str})
            assert list(a[key]) == list(b[key]), (d, streamed)
            pd.testing.assert_frame_equal(a, b[a.columns], check_exact=False, rtol=1e-8, atol=0)
