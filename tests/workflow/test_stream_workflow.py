"""The scattered streamed load (target `stream`: one job per take, gathered, ranked, the held-out
takes evaluated block by block) against the study's whole-take rules, on the dense study's
talker (TRC, 468 points) and the default study's S1 (C3D, head markers, copy_markers 13=11):
the gathered Gram is the training rows' A^T A of the study's displacements.npz to round-off,
with the same pivots; its r values and held-out error curve are the study's to the digits the
tables print."""

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from helpers import REPO, SHARED_DATA

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ranking.qr import rank_from_gram

pytestmark = pytest.mark.workflow

CONFIG = """\
study: streamcheck
subjects: {sheet}
shared_data: {shared}
default_datasets: false
datasets:
  dense4:
    subject: {subject}
    train: "1-3"
    heldout: "4"
memory:
  max_gib: 0.25
"""


@pytest.mark.parametrize("sheet,subject", [("dense_subjects.tsv", "dense468"),
                                           ("subjects.tsv", "S1")])
def test_the_gathered_gram_is_the_whole_take_loads(tmp_path, sheet, subject):
    (tmp_path / "c.yaml").write_text(CONFIG.format(sheet=REPO / "config" / sheet,
                                                   shared=SHARED_DATA, subject=subject))
    root = tmp_path / "results" / "streamcheck" / "dense4"
    targets = [str((root / f).relative_to(tmp_path))
               for f in ("stream/gram.npz", "data/displacements.npz", "stream/r_values.tsv",
                         "stream/error_curve.tsv", "qr/r_values.tsv", "eval/error_curve.tsv")]
    cmd = [sys.executable, "-m", "snakemake", *targets, "-s", str(REPO / "Snakefile"),
           "--directory", str(tmp_path), "--cores", "2", "--configfile", str(tmp_path / "c.yaml")]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    with np.load(root / "stream" / "gram.npz") as g:
        G, rows, labels = g["gram"], int(g["rows"]), [str(x) for x in g["labels"]]
    d = load_displacements(root / "data" / "displacements.npz")
    train = d.A[np.isin(d.row_sentence, [0, 1, 2])]
    assert labels == d.labels and rows == train.shape[0]
    ref = train.T @ train
    np.testing.assert_allclose(G, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    ours, theirs = rank_from_gram(G, rows, labels), rank_from_gram(ref, rows, d.labels)
    assert list(ours.order) == list(theirs.order)
    np.testing.assert_allclose(ours.r, theirs.r, rtol=1e-9)
    for i in range(4):  # each take's rows of A are the study's
        part = load_displacements(root / "stream" / "takes" / f"t{i + 1:03d}.npz").A
        np.testing.assert_array_equal(part, d.A[d.row_sentence == i])
    log = (tmp_path / "results" / "streamcheck" / "logs" / "stream_take" / "dense4"
           / "t001.log").read_text()
    assert "memory.max_gib = 0.25" in log
    pairs = (("stream/r_values.tsv", "qr/r_values.tsv", "marker"),
             ("stream/error_curve.tsv", "eval/error_curve.tsv", "main_markers"))
    for streamed, whole, key in pairs:
        a = pd.read_csv(root / streamed, sep="\t", dtype={key: str}, keep_default_na=False)
        b = pd.read_csv(root / whole, sep="\t", dtype={key: str}, keep_default_na=False)
        assert list(a[key]) == list(b[key])  # the pivots
        pd.testing.assert_frame_equal(a, b[a.columns], check_exact=False, rtol=1e-8, atol=0)
