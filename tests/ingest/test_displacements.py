"""The displacement matrix A: layout, neutral subtraction, checks, npz round trip."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.displacement_file import load_displacements, save_displacements
from facemotion.ingest.displacements import Displacements, build_displacements, sentence_rows
from facemotion.io.recording import Recording

LABELS = ["Chin", "40", "L017"]


def take(F, seed, source, labels=LABELS, rate=60.0):
    rng = np.random.default_rng(seed)
    return Recording(labels, rng.uniform(-100, 100, size=(F, len(labels), 3)), rate,
                     source=source)


def two_takes():
    a, b = take(5, 1, "a.c3d"), take(7, 2, "b.c3d")
    a.filled[2, 1] = True
    return a, b


def test_layout_and_neutral_subtraction():
    a, b = two_takes()
    d = build_displacements([a, b], ["s1", "s2"], head_residuals=[np.full(5, 0.1),
                                                                   np.full(7, 0.2)])
    assert d.A.shape == (3 * 12, 3)
    assert d.labels == LABELS and d.sentences == ["s1", "s2"] and d.rate == 60.0
    # element by element, from the definition: row 3f + c, column j
    for s, rec, offset in ((0, a, 0), (1, b, 5)):
        for f in range(rec.n_frames):
            for c in range(3):
                row = 3 * (offset + f) + c
                assert d.row_sentence[row] == s and d.row_frame[row] == f
                for j in range(3):
                    assert d.A[row, j] == rec.points[f, j, c] - rec.points[0, j, c]
    assert np.all(d.A[0:3] == 0) and np.all(d.A[15:18] == 0)  # each sentence's first frame
    np.testing.assert_allclose(d.neutral, (a.points[0] + b.points[0]) / 2)
    assert d.fill_mask.shape == (12, 3) and d.fill_mask[2, 1] and d.fill_mask.sum() == 1
    np.testing.assert_allclose(d.head_residual, [0.1] * 5 + [0.2] * 7)
    np.testing.assert_allclose(d.frames()[5:], b.points - b.points[0])


def test_mean_first_10_neutral():
    a = take(15, 3, "a.c3d")
    d = build_displacements([a], ["s"], neutral="mean_first_10")
    np.testing.assert_allclose(d.A[3 * 4 + 2], a.points[4, :, 2] - a.points[:10, :, 2].mean(0))
    np.testing.assert_allclose(d.frames()[:10].mean(axis=0), 0, atol=1e-12)
    assert np.all(d.head_residual == 0)
    with pytest.raises(InputError, match="neutral"):
        build_displacements([a], ["s"], neutral="median")


def test_rows_for_and_subset():
    a, b = two_takes()
    c = take(4, 9, "c.c3d")
    d = build_displacements([a, b, c], ["s1", "s2", "s3"])
    m = d.rows_for([1])
    assert m.sum() == 21 and np.all(np.flatnonzero(m) == np.arange(15, 36))
    sub = d.subset([2, 0])
    assert sub.sentences == ["s3", "s1"]
    np.testing.assert_array_equal(sub.A, np.concatenate([d.A[36:48], d.A[0:15]]))
    np.testing.assert_array_equal(sub.row_sentence, [0] * 12 + [1] * 15)
    np.testing.assert_array_equal(sub.row_frame[::3], list(range(4)) + list(range(5)))
    assert sub.fill_mask.shape == (9, 3) and sub.fill_mask[4 + 2, 1]
    np.testing.assert_allclose(sub.neutral, (a.points[0] + c.points[0]) / 2)
    with pytest.raises(InputError, match="out of range"):
        d.subset([3])


def test_label_and_rate_mismatch():
    a, _ = two_takes()
    other = take(5, 4, "odd.c3d", labels=["Chin", "41", "L017"])
    with pytest.raises(InputError, match=r"odd\.c3d.*extra markers 41.*missing markers 40"):
        build_displacements([a, other], ["s1", "s2"])
    swapped = take(5, 4, "swap.c3d", labels=["40", "Chin", "L017"])
    with pytest.raises(InputError, match=r"swap\.c3d.*different order"):
        build_displacements([a, swapped], ["s1", "s2"])
    with pytest.raises(InputError, match=r"fast\.c3d.*120.0 Hz"):
        build_displacements([a, take(5, 5, "fast.c3d", rate=120.0)], ["s1", "s2"])


def test_nan_left_is_an_error():
    a, b = two_takes()
    b.points[3, 2, 1] = np.nan
    b.points[6, 0, 0] = np.nan
    with pytest.raises(InputError, match=r"b\.c3d: marker 'L017' is missing at t = 0\.050 s"):
        build_displacements([a, b], ["s1", "s2"])


def test_save_load_round_trip_and_byte_identical(tmp_path):
    a, b = two_takes()
    d = build_displacements([a, b], ["s1", "s2"], head_residuals=[np.arange(5.0),
                                                                   np.arange(7.0)])
    save_displacements(tmp_path / "d.npz", d)
    back = load_displacements(tmp_path / "d.npz")
    assert isinstance(back, Displacements)
    for name in ("A", "row_sentence", "row_frame", "fill_mask", "head_residual", "neutral",
                 "sentence_neutral"):
        np.testing.assert_array_equal(getattr(back, name), getattr(d, name))
        assert getattr(back, name).dtype == getattr(d, name).dtype
    assert back.labels == d.labels and back.sentences == d.sentences and back.rate == d.rate
    assert all(type(x) is str for x in back.labels)
    # an independent reader: numpy's own npz loader
    with np.load(tmp_path / "d.npz", allow_pickle=False) as z:
        np.testing.assert_array_equal(z["A"], d.A)
    first = (tmp_path / "d.npz").read_bytes()
    save_displacements(tmp_path / "d2.npz", back)
    assert (tmp_path / "d2.npz").read_bytes() == first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npz", "d2.npz"]


def test_load_errors(tmp_path):
    with pytest.raises(InputError, match=r"none\.npz.*not found"):
        load_displacements(tmp_path / "none.npz")
    np.savez(tmp_path / "partial.npz", A=np.zeros((3, 2)))
    with pytest.raises(InputError, match=r"partial\.npz.*lacks.*labels"):
        load_displacements(tmp_path / "partial.npz")


def test_sentence_order_is_first_appearance_and_rows_may_interleave():
    rs = np.repeat([3, 3, 1, 1, 3], 3)
    ids, groups = sentence_rows(rs, rs.size)
    assert ids.tolist() == [3, 1]
    assert groups[0].tolist() == [0, 1, 2, 3, 4, 5, 12, 13, 14]
