"""The validation layer: outliers found at exactly the planted samples, none on real data;
units checked by the spread of the face; take length; the sheet's units never override the
file's. References: planted ground truth, and the real recordings in ../shared/data."""

import re

import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.ingest.validation import (
    Limits,
    check_face_spread,
    check_take,
    face_spread,
    find_outliers,
)
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording
from facemotion.io.registry import read_recording
from facemotion.io.wide_csv import write_csv

ROOT = SHARED_DATA
REAL = sorted(ROOT.glob("animface/*.c3d")) + sorted(ROOT.glob("grid/*.trc"))


@pytest.fixture(scope="module")
def jaw():
    """400 frames of the AnimFace jaw take (60 Hz, 41 markers)."""
    rec = read_c3d(ROOT / "animface" / "animface_jaw.c3d")
    return Recording(rec.labels, rec.points[200:600], rec.rate, source="jaw")


def planted(rec, spots, values):
    pts = rec.points.copy()
    truth = np.zeros(pts.shape[:2], dtype=bool)
    for (f, j), v in zip(spots, values, strict=True):
        pts[f, j] = v
        truth[f, j] = True
    return Recording(rec.labels, pts, rec.rate, source="planted"), truth


def test_no_outlier_and_plausible_spread_on_every_real_take():
    assert len(REAL) == 8
    for path in REAL:
        rec = read_recording(path, path.suffix[1:])
        mask, notes = find_outliers(rec, Limits())
        assert not mask.any(), (path.name, notes[:3])
        assert 40 < face_spread(rec) < 65, path.name


def test_planted_spikes_are_found_exactly(jaw):
    rng = np.random.default_rng(0)
    spots = [(int(f), int(j)) for f, j in zip(rng.choice(400, 12, replace=False),
                                              rng.integers(0, 41, 12), strict=True)]
    centre = np.median(jaw.points, axis=1)
    values = []
    for i, (f, j) in enumerate(spots):
        if i == 0:
            values.append(np.array([1e30, 0, 0]))                 # a corrupt value
        elif i % 2:
            values.append(jaw.points[f, j] + [0, 0, 800.0])       # a flipped exponent bit
        else:
            values.append(jaw.points[f, j] + [30.0, 0, 0])        # 30 mm in 1/60 s: 1.8 m/s
    rec, truth = planted(jaw, spots, values)
    mask, notes = find_outliers(rec, Limits())
    np.testing.assert_array_equal(mask, truth)
    assert len(notes) == len({j for _, j in spots})
    assert centre.shape == (400, 3)


def test_a_stretch_on_another_point_and_a_lasting_step(jaw):
    j = jaw.index("Chin")
    pts = jaw.points.copy()
    pts[100:110, j] += [0, 40.0, 0]       # the tracker follows another point for 10 frames
    pts[300:, j] += [0, 0, 25.0]          # a step that lasts to the end (100 frames)
    rec = Recording(jaw.labels, pts, jaw.rate, source="swap")
    mask, notes = find_outliers(rec, Limits())
    truth = np.zeros_like(mask)
    truth[100:110, j] = truth[300:, j] = True
    np.testing.assert_array_equal(mask, truth)
    assert "marker 'Chin': 110 outlier sample(s) in 2 run(s), first at frame 101" in notes[0]


def test_gap_is_bridged_at_the_speed_over_the_gap(jaw):
    # a marker missing for 30 frames comes back 20 mm away: 20 mm in 0.5 s is plausible
    j = 3
    pts = jaw.points.copy()
    pts[200:230, j] = np.nan
    pts[230:, j] += [20.0, 0, 0]
    rec = Recording(jaw.labels, pts, jaw.rate, source="gap")
    assert not find_outliers(rec, Limits())[0].any()


def test_outliers_error_mode_names_marker_and_frame(jaw):
    rec, _ = planted(jaw, [(50, 2)], [jaw.points[50, 2] + [0, 0, 800.0]])
    with pytest.raises(InputError, match=rf"planted: marker '{jaw.labels[2]}': 1 outlier "
                       r"sample\(s\).*frame 51 \(t = 0\.833 s\): 1 at up to 7\d\d mm from the "
                       r"face centre \(limit 250 mm, limits\.max_distance_mm\).*"
                       r"\(limits\.outliers is .error.\)"):
        check_take(rec, Limits(outliers="error"))
    clean, found = check_take(rec, Limits())
    assert np.isnan(clean.points[50, 2]).all() and found.outliers.sum() == 1
    assert np.isfinite(clean.points[np.arange(400) != 50]).all()


MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


@pytest.mark.parametrize("true,declared", [("m", "mm"), ("mm", "m"), ("cm", "mm"),
                                           ("mm", "cm"), ("in", "mm"), ("mm", "in")])
def test_wrong_units_stop_with_the_spread_measured(tmp_path, jaw, true, declared):
    """A face recorded in ``true`` units, read in the ``declared`` ones (a CSV in metres read
    as millimetres, ...): every such mix-up is outside 10-300 mm."""
    write_csv(tmp_path / "take.csv", Recording(jaw.labels, jaw.points / MM[true], jaw.rate))
    rec = read_recording(tmp_path / "take.csv", "csv", units=declared)
    measured = face_spread(jaw) / MM[true] * MM[declared]
    with pytest.raises(InputError, match=rf"take\.csv: the markers lie a median "
                       rf"{re.escape(f'{measured:.3g}')} mm from their centre when read in "
                       rf"{declared} "
                       r"\(as the subject sheet says\); a face spans 10-300 mm"):
        check_face_spread(rec, Limits())
    right = read_recording(tmp_path / "take.csv", "csv", units=true)
    assert check_face_spread(right, Limits()) == pytest.approx(face_spread(jaw), rel=1e-4)


def test_right_units_pass_and_the_file_wins_over_the_sheet(tmp_path, jaw):
    write_c3d(tmp_path / "take.c3d", jaw)
    rec = read_recording(tmp_path / "take.c3d", "c3d", units="m")  # the sheet says m
    clean, found = check_take(rec, Limits(), sheet_units="m")
    assert (found.units, found.units_source, found.units_conflict) == ("mm", "file",
                                                                       "sheet says m")
    np.testing.assert_allclose(clean.points, jaw.points, atol=1e-4)
    assert check_take(rec, Limits(), sheet_units="mm")[1].units_conflict == ""


def test_short_take(jaw):
    one = Recording(jaw.labels, jaw.points[:1], jaw.rate, source="one.c3d")
    with pytest.raises(InputError, match=r"one\.c3d: heldout take has 1 frame\(s\), fewer than "
                       r"the minimum 10 \(limits\.min_take_frames\)"):
        check_take(one, Limits(), role="heldout")
    check_take(Recording(jaw.labels, jaw.points[:10], jaw.rate), Limits())


def test_bad_limits_name_the_argument_or_the_name_given():
    with pytest.raises(InputError, match=r"^limits\.outliers: must be one of gaps, error"):
        Limits(outliers="drop")
    with pytest.raises(InputError, match=r"^limits\.face_spread_mm: need 0 < low < high"):
        Limits(face_spread_mm=(300, 10))
    with pytest.raises(InputError, match=r"^limits\.max_speed_mm_s: must be positive"):
        Limits(max_speed_mm_s=0)
    with pytest.raises(InputError, match=r"^setting gaps\.max_speed_mm_s: must be positive"):
        Limits(max_speed_mm_s=0, names={"max_speed_mm_s": "setting gaps.max_speed_mm_s"})


def test_nanmedian_over_markers_equals_numpys():
    from facemotion.ingest.validation import _nanmedian_markers

    rng = np.random.default_rng(0)
    for shape in ((50, 7, 3), (40, 8, 3), (30, 9), (20, 1, 3)):
        x = rng.standard_normal(shape)
        x[rng.random(shape) < 0.3] = np.nan
        x[0] = np.nan  # a frame with nothing measured
        with np.errstate(all="ignore"), pytest.warns(RuntimeWarning):
            ref = np.nanmedian(x, axis=1, keepdims=True)
        np.testing.assert_array_equal(_nanmedian_markers(x), ref)


def test_median_over_markers_of_full_frames_equals_numpys():
    """One partition and a maximum give numpy's median (two partitions) exactly: odd and even
    counts, ties, infinities; and a value off by one order statistic is told apart."""
    from facemotion.ingest.validation import _median_full

    rng = np.random.default_rng(1)
    for shape in ((50, 7, 3), (40, 8, 3), (30, 468), (20, 1, 3), (20, 2)):
        x = rng.standard_normal(shape)
        x[1] = 0.5                                   # every marker equal
        x[2, : shape[1] // 2] = np.inf               # infinities on the lower half
        x[3] = np.round(x[3])                        # ties
        with np.errstate(invalid="ignore"):
            ref = np.median(x, axis=1, keepdims=True)
            got = _median_full(x)
        np.testing.assert_array_equal(got, ref)
    x = np.arange(8.0)[None]
    assert _median_full(x)[0, 0] == 3.5 != np.sort(x)[0, 3]


def test_vectorised_outlier_screen_equals_the_per_marker_test():
    """find_outliers sends only markers with a gap, a far sample or a fast step to the
    piecewise test: the mask equals the piecewise test run on every marker (reference), and
    the centre distances equal numpy's nanmedian-based ones."""
    from facemotion.ingest.validation import _reachable, centre_distances

    rng = np.random.default_rng(3)
    F, n = 700, 40
    pts = 40.0 * rng.standard_normal((1, n, 3)) + np.cumsum(
        0.3 * rng.standard_normal((F, n, 3)), axis=0)
    pts[100, 3] += 80.0                      # a spike (fast)
    pts[300:320, 7] += 60.0                  # a lasting step (fast)
    pts[50:60, 11] = np.nan                  # a gap
    pts[400, 20] += [500.0, 0.0, 0.0]        # far from the centre
    pts[10, :38] = np.nan                    # a frame with 2 markers measured
    rec = Recording([f"m{j}" for j in range(n)], pts, 100.0, source="planted")
    lim = Limits()
    mask, notes = find_outliers(rec, lim)
    ok = np.isfinite(pts).all(axis=2)
    with np.errstate(all="ignore"):
        p = np.where(ok[..., None], pts, np.nan)
        ref_dist = np.linalg.norm(p - np.nanmedian(p, axis=1, keepdims=True), axis=2)
    ref_dist[ok.sum(axis=1) < 3] = np.nan
    dist, enough = centre_distances(rec)
    np.testing.assert_allclose(dist, ref_dist, rtol=1e-12, atol=0)
    far = np.nan_to_num(ref_dist, nan=0.0) > lim.max_distance_mm
    ref = far.copy()
    for j in range(n):
        idx = np.flatnonzero(ok[:, j] & ~far[:, j])
        keep = _reachable(pts[idx, j], idx, rec.rate, lim.max_speed_mm_s)
        ref[idx[~keep], j] = True
    np.testing.assert_array_equal(mask, ref)
    assert mask[100, 3] and mask[300:320, 7].all() and mask[400, 20]
    assert {note.split("'")[1] for note in notes} == {"m3", "m7", "m20"}


def test_same_face_across_takes(jaw):
    """One-second windows of the jaw exercise (mouth held open in some) are the same face;
    a mirrored take and a take with its labels shuffled are not."""
    from facemotion.ingest.validation import check_same_shape

    rec = read_c3d(ROOT / "animface" / "animface_jaw.c3d")
    windows = [Recording(rec.labels, rec.points[a:a + 60], rec.rate, source=f"w{a}")
               for a in range(0, 1530, 60)]
    rms = check_same_shape(windows, Limits())
    assert max(rms) < 10 and rms[0] == 0
    mirrored = Recording(jaw.labels, jaw.points * [1, 1, -1], jaw.rate, source="mirror.c3d")
    with pytest.raises(InputError, match=r"mirror\.c3d: the face is a mirror image of w0's"):
        check_same_shape([windows[0], mirrored], Limits())
    order = np.random.default_rng(0).permutation(jaw.n_markers)
    shuffled = Recording(jaw.labels, jaw.points[:, order], jaw.rate, source="shuffled.c3d")
    with pytest.raises(InputError, match=r"shuffled\.c3d: the face differs from w0's by "
                       r"\d+.* mm RMS.*limits\.max_shape_rms_mm"):
        check_same_shape([windows[0], shuffled], Limits())


def test_rate_outside_the_plausible_range(jaw):
    slow = Recording(jaw.labels, jaw.points, 0.06, source="ms.csv")
    with pytest.raises(InputError, match=r"ms\.csv: frame rate 0\.06 Hz is outside 10-2000 Hz"):
        check_take(slow, Limits())
    check_take(Recording(jaw.labels, jaw.points, 25.0), Limits())


def test_frozen_take_and_still_markers(jaw):
    """A take in which nothing moves is an error; a marker that is perfectly still (a still
    head in synthetic data, a coarse export) is not an outlier."""
    from facemotion.ingest.validation import check_moves

    frozen = Recording(jaw.labels, np.repeat(jaw.points[:1], 30, axis=0), jaw.rate,
                       source="frozen.c3d")
    with pytest.raises(InputError, match=r"frozen\.c3d: no marker moves in this take"):
        check_take(frozen, Limits())
    pts = jaw.points.copy()
    pts[:, :6] = pts[0, :6]  # the head markers exactly still
    check_moves(Recording(jaw.labels, pts, jaw.rate))
    assert not find_outliers(Recording(jaw.labels, pts, jaw.rate), Limits())[0].any()
