"""Filling a marker's gaps by copying another marker's displacement (the authors' S1 fill)."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.copy_fill import copy_fill, parse_copy_markers
from facemotion.io.recording import Recording

LABELS = ["a", "b", "c"]


def take(seed, n=50, lose=None):
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.normal(0, 0.3, (n, 3, 3)), axis=0) + [[0, 0, 0], [30, 0, 0], [0, 40, 0]]
    if lose is not None:
        pts[lose, 0] = np.nan
    return Recording(LABELS, pts, 100.0, f"take{seed}")


def test_parse_pairs_and_bad_specs():
    assert parse_copy_markers("13=11") == [("13", "11")]
    assert parse_copy_markers(" 13 = 11, 20=21 ,") == [("13", "11"), ("20", "21")]
    assert parse_copy_markers(["13=11"]) == [("13", "11")]
    assert parse_copy_markers(None) == [] and parse_copy_markers("") == []
    for bad, needle in (("13", "TARGET=SOURCE"), ("13=13", "TARGET=SOURCE"), ("=11", "TARGET"),
                        ("13=11,13=12", "filled twice"), ("13=11,11=12", "both filled")):
        with pytest.raises(InputError, match=needle):
            parse_copy_markers(bad, "sheet row 2: copy_markers")


def test_copied_displacement_equals_the_source_exactly():
    """Where 'a' is lost its displacement from the take's first frame is 'b''s, exactly; its
    measured samples are untouched; the copies are flagged."""
    lose = np.zeros(50, bool)
    lose[1:] = True                                  # measured only in the first frame
    lose2 = np.zeros(50, bool)
    lose2[10:30] = True                              # a gap in the middle
    recs = [take(1, lose=lose), take(2, lose=lose2)]
    out, counts = copy_fill(recs, [("a", "b")])
    assert counts == {"a": 49 + 20}
    for r, orig, lost in zip(out, recs, (lose, lose2), strict=True):
        d_a = r.points[:, 0] - r.points[0, 0]
        d_b = r.points[:, 1] - r.points[0, 1]
        np.testing.assert_allclose(d_a[lost], d_b[lost], atol=1e-12)
        assert np.array_equal(r.points[~lost, 0], orig.points[~lost, 0])
        assert np.array_equal(r.filled[:, 0], lost) and not r.filled[:, 1:].any()
        assert np.isnan(orig.points[lost, 0]).all()              # inputs not modified


def test_take_without_the_target_uses_the_median_offset_and_errors():
    lose_all = np.ones(50, bool)
    recs = [take(1), take(2, lose=lose_all)]
    out, _ = copy_fill(recs, [("a", "b")])
    offsets = recs[0].points[:, 0] - recs[0].points[:, 1]
    np.testing.assert_allclose(out[1].points[:, 0] - out[1].points[:, 1],
                               np.broadcast_to(np.median(offsets, axis=0), (50, 3)))
    with pytest.raises(InputError, match="never measured in the same frame"):
        copy_fill([take(2, lose=lose_all)], [("a", "b")])
    with pytest.raises(InputError, match="marker 'z'"):
        copy_fill([take(1)], [("z", "b")])
    # where the source is missing too, the sample stays missing (for the gap filling)
    r = take(3, lose=np.r_[np.zeros(5, bool), np.ones(45, bool)])
    r.points[20, 1] = np.nan
    out, counts = copy_fill([r], [("a", "b")])
    assert np.isnan(out[0].points[20, 0]).all() and counts["a"] == 44


def test_s1_through_the_loading_path(tmp_path):
    """The virtual S1 as C3D files: with the sheet's 13=11 the loading path makes A's column
    13 equal to column 11 (head coordinates, after the head alignment), and the gap report
    says so; without it, 13 cannot be filled."""
    from facemotion.ingest.loading import load_dataset
    from facemotion.io.c3d import write_c3d
    from facemotion.virtual.talker import simulate_subject

    subj = simulate_subject("S1", seed=1, n_sentences=3, sentence_duration=(0.8, 1.0))
    paths = []
    for i, rec in enumerate(subj.recordings):
        paths.append(str(tmp_path / f"S1_s{i + 1:02d}.c3d"))
        write_c3d(paths[-1], rec)
    head = [f"H{i}" for i in range(1, 7)]
    out = load_dataset(paths, "c3d", head_markers=head, exclude_markers=head, train=[0, 1],
                       heldout=[2], copy_markers=[("13", "11")])
    d = out.displacements
    a13, a11 = d.A[:, d.labels.index("13")], d.A[:, d.labels.index("11")]
    # equal wherever 13 was copied; apart only in the frame where it was measured on its own
    # (S1_TRACKED_13: the second frame of the first sentence; rows 3-5)
    diff = np.abs(a13 - a11).reshape(-1, 3).max(axis=1)
    assert np.flatnonzero(diff > 1e-9).tolist() == [1]
    assert np.max(np.abs(a11)) > 1e-9
    rep = out.gap_report.set_index("marker")
    frames = int(subj.truth["sentence_frames"].sum())
    lost = frames - 3 - 1                 # all but each sentence's first frame and one more
    assert rep.loc["13", "missing_frames"] == lost
    assert rep.loc["13", "filled_frames"] == lost
    assert rep.loc["13", "fill_method"].startswith("copy:11")
    assert out.filled[:, d.labels.index("13")].sum() == lost
    with pytest.raises(InputError, match="'13'"):
        load_dataset(paths, "c3d", head_markers=head, exclude_markers=head, train=[0, 1],
                     heldout=[2])
