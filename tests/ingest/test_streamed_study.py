"""The streamed loader on the study's own virtual subjects, against the whole-take path the
study runs (load_dataset, then the study's ranking and the held-out error curve): the same
pivots; r values and errors to 1e-9 relative (the takes are filled where they have gaps: the
window fill agrees with the whole-take fill to FILL_RTOL, the same 1e-9)."""

from pathlib import Path

import numpy as np
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


@pytest.mark.parametrize("subject", ["S2a", "S2b"])
def test_the_default_studys_virtual_datasets(tmp_path, subject):
    """S2a and S2b as the default study makes and loads them: 50 sentences of the 57-marker
    talker as C3D, 30 to train, 20 held out, head markers aligned then left out."""
    sheet = read_sheet_table(Path(__file__).parents[2] / "config" / "subjects.tsv")
    sheet = sheet.set_index("subject")
    row = sheet.loc[subject]
    paths, _ = write_virtual_subject(tmp_path / "data", subject, row["simulate"], fmt="c3d",
                                     seed=int(row["seed"]), n_sentences=int(row["n_sentences"]))
    head = str(row["head_markers"]).split(",")
    whole = _compare(paths, "c3d", tmp_path, 30, head_markers=head, exclude_markers=head,
                     units="mm")
    assert whole.displacements.A.shape[1] == 57


def test_s1s_copied_marker_is_refused_by_the_streamed_loader_in_one_line(tmp_path):
    """S1 copies marker 11 into 13 (copy_markers, a median over every take): the streamed
    loader does not take it and says so."""
    paths, _ = write_virtual_subject(tmp_path, "S1", "S1", fmt="c3d", seed=1, n_sentences=3)
    with pytest.raises(InputError, match=r"^copy_markers: not supported by the streamed loader"):
        stream_dataset([str(p) for p in paths], "c3d", tmp_path / "A.npz", train=[0, 1],
                       heldout=[2], copy_markers=[("13", "11")])


@pytest.mark.parametrize("fmt", ["trc", "c3d"])
def test_a_small_dense_virtual_dataset(tmp_path, fmt):
    """The dense talker (468 face-mesh vertices), 6 sentences, 4 to train."""
    from facemotion.virtual.talker import HEAD_LABELS

    paths, _ = write_virtual_subject(tmp_path / "data", "D", "D468", fmt=fmt, seed=5,
                                     n_sentences=6, shared_data=SHARED_DATA)
    head = list(HEAD_LABELS)
    whole = _compare(paths, fmt, tmp_path, 4, head_markers=head, exclude_markers=head)
    assert whole.displacements.A.shape[1] == 468
