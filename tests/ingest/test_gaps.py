"""Gap report and gap filling: planted gaps in clean recordings, compared with the truth."""

import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.ingest.gaps import REPORT_COLUMNS, fill_gaps, gap_report
from facemotion.io.recording import Recording


def sinusoid(freq, rate=120.0, F=1200, amp=5.0, phase=0.3):
    t = np.arange(F) / rate
    P = np.zeros((F, 2, 3))
    P[:, 0, 0] = amp * np.sin(2 * np.pi * freq * t + phase)
    P[:, 0, 1] = amp * np.cos(2 * np.pi * freq * t + 2 * phase)
    P[:, 0, 2] = 100.0
    P[:, 1] = [10.0, 20.0, 30.0]
    return Recording(["Mouth_Up", "Chin"], P, rate, source="sine.c3d")


@pytest.mark.parametrize("freq", [1.0, 2.0, 5.0])
@pytest.mark.parametrize("start", [300, 517])
def test_cubic_error_within_hermite_bound(freq, start):
    rec = sinusoid(freq)
    gap = rec.points.copy()
    gap[start:start + 12, 0] = np.nan  # 0.1 s at 120 Hz
    filled, rep = fill_gaps(Recording(rec.labels, gap, rec.rate, rec.source), max_interp_s=0.1)
    err = np.abs(filled.points - rec.points).max()
    h = 13 / rec.rate  # between the measured samples either side
    bound = h ** 4 / 384 * 5.0 * (2 * np.pi * freq) ** 4
    assert err <= 1.25 * bound
    if freq <= 2.0:
        assert err < 0.06  # the documented figure: 0.1 s gap, 5 mm, 2 Hz, 120 Hz
    assert rep.loc[0, "fill_method"] == "cubic" and rep.loc[1, "fill_method"] == "none"
    assert rep.loc[0, "filled_frames"] == 12


def correlated(F=1000, n=20, noise=0.05, seed=0, rate=100.0):
    """n markers driven by 3 smooth sources plus independent noise (mm)."""
    rng = np.random.default_rng(seed)
    t = np.arange(F) / rate
    S = 5 * np.stack([np.sin(2 * np.pi * 1.3 * t), np.sin(2 * np.pi * 0.7 * t + 1),
                      np.cos(2 * np.pi * 2.1 * t)], axis=1)
    X = S @ rng.standard_normal((3, 3 * n)) + 30 * rng.standard_normal((1, 3 * n))
    X += noise * rng.standard_normal(X.shape)
    return Recording([f"L{j:03d}" for j in range(n)], X.reshape(F, n, 3), rate,
                     source="corr.trc")


def test_pca_fills_long_gaps_from_correlated_markers():
    truth = correlated()
    pts = truth.points.copy()
    pts[300:400, 4] = np.nan  # 1 s
    pts[600:700, 7] = np.nan
    pts[:50, 2] = np.nan  # start of take: cannot be interpolated
    pts[800:803, 9] = np.nan  # short: cubic
    filled, rep = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source))
    miss = np.isnan(pts).any(axis=2)
    err = (filled.points - truth.points)[miss]
    assert np.sqrt(np.mean(err ** 2)) < 0.1
    assert np.abs(err).max() < 0.4
    # a naive fill (marker's mean position) is far worse: the test can tell
    naive = np.nanmean(pts, axis=0)
    naive_err = (np.broadcast_to(naive, pts.shape) - truth.points)[miss]
    assert np.sqrt(np.mean(naive_err ** 2)) > 20 * np.sqrt(np.mean(err ** 2))
    methods = dict(zip(rep["marker"], rep["fill_method"], strict=True))
    assert methods["L004"] == methods["L007"] == methods["L002"] == "pca"
    assert methods["L009"] == "cubic" and methods["L000"] == "none"
    np.testing.assert_array_equal(filled.filled, miss)
    assert np.isfinite(filled.points).all()


def test_pca_without_complete_frames():
    truth = correlated(F=400, n=12, seed=1)
    pts = truth.points.copy()
    pts[:210, 0] = np.nan  # overlapping start and end gaps: no frame has every marker
    pts[190:, 1] = np.nan
    pts[100:150, 5] = np.nan
    filled, rep = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source),
                            max_interp_s=0.0)
    miss = np.isnan(pts).any(axis=2)
    assert not (~miss).all(axis=1).any()
    err = (filled.points - truth.points)[miss]
    assert np.sqrt(np.mean(err ** 2)) < 0.2
    assert set(rep.loc[rep["missing_frames"] > 0, "fill_method"]) == {"pca"}


def test_pca_gap_with_nothing_to_learn_from_is_an_error():
    truth = correlated(F=100, n=3)
    pts = truth.points.copy()
    pts[:60, 0] = np.nan
    pts[50:, 1] = np.nan
    pts[55:, 2] = np.nan  # no other marker is measured throughout L000's gap: no donor
    with pytest.raises(InputError, match=r"corr\.trc: marker 'L00\d'.*cannot reconstruct"):
        fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source))


def test_mask_flags_exactly_the_filled_samples_and_keeps_producer_flags():
    truth = correlated(F=300, n=6, seed=2)
    pts = truth.points.copy()
    pts[10:14, 1] = np.nan
    pts[100:180, 3] = np.nan
    pts[200, 4, 1] = np.nan  # one coordinate missing: the whole sample counts as missing
    producer = np.zeros((300, 6), dtype=bool)
    producer[50:60, 0] = True
    filled, rep = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source, producer))
    expected = producer.copy()
    expected[10:14, 1] = expected[100:180, 3] = expected[200, 4] = True
    np.testing.assert_array_equal(filled.filled, expected)
    # measured samples are untouched
    keep = ~expected
    np.testing.assert_array_equal(filled.points[keep], truth.points[keep])
    assert list(rep.columns) == REPORT_COLUMNS
    row = rep.set_index("marker")
    assert row.loc["L003", "missing_frames"] == 80 and row.loc["L003", "longest_gap_frames"] == 80
    assert row.loc["L004", "missing_frames"] == 1
    assert row.loc["L000", "filled_frames"] == 10 and row.loc["L000", "fill_method"] == "none"
    assert row.loc["L003", "missing_fraction"] == pytest.approx(80 / 300)


def test_gap_report_counts():
    pts = np.ones((20, 2, 3))
    pts[2:5, 0] = np.nan
    pts[8, 0] = np.nan
    pts[15:20, 0] = np.nan
    rep = gap_report(Recording([40, "Chin"], pts, 10.0))
    assert rep["marker"].tolist() == ["40", "Chin"]
    r = rep.iloc[0]
    assert (r["missing_frames"], r["n_gaps"], r["longest_gap_frames"]) == (9, 3, 5)
    assert r["missing_fraction"] == pytest.approx(0.45)
    assert rep.iloc[1]["missing_frames"] == 0 and rep.iloc[1]["n_gaps"] == 0


def test_marker_missing_everywhere_is_an_error():
    truth = correlated(F=50, n=4)
    pts = truth.points.copy()
    pts[:, 2] = np.nan
    with pytest.raises(InputError, match=r"corr\.trc.*L002.*every frame"):
        fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source))


def test_error_mode_names_marker_and_gap_start():
    truth = correlated(F=300, n=5)
    pts = truth.points.copy()
    pts[5:7, 0] = np.nan  # short: fine
    pts[120:160, 3] = np.nan  # 0.4 s at 100 Hz: long
    with pytest.raises(InputError, match=r"corr\.trc: marker 'L003'.*t = 1\.200 s"):
        fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source), max_interp_s=0.1,
                  long_gaps="error")
    pts[120:160, 3] = truth.points[120:160, 3]
    filled, _ = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source),
                          long_gaps="error")
    assert np.isfinite(filled.points).all()


def test_bad_settings():
    rec = correlated(F=20, n=3)
    with pytest.raises(InputError, match="long_gaps"):
        fill_gaps(rec, long_gaps="spline")
    with pytest.raises(InputError, match="max_interp_s"):
        fill_gaps(rec, max_interp_s=-1)


def dense_face(frames, rate=30.0, seed=0, n_sources=12, noise=0.05):
    """The canonical mesh's 468 vertices (mm) moved by smooth Gaussian-bump fields + noise."""

    from facemotion.io.obj import read_obj

    data = SHARED_DATA
    v = 10.0 * read_obj(data / "mesh" / "canonical_face_model.obj")[0]
    rng = np.random.default_rng(seed)
    c = v[rng.integers(0, len(v), n_sources)]
    sigma = rng.uniform(15.0, 40.0, n_sources)
    W = np.exp(-((v[None] - c[:, None]) ** 2).sum(-1) / (2 * sigma[:, None] ** 2))
    d = rng.standard_normal((n_sources, 3))
    d *= rng.uniform(1.0, 4.0, (n_sources, 1)) / np.linalg.norm(d, axis=1, keepdims=True)
    t = np.arange(frames) / rate
    src = np.sin(2 * np.pi * rng.uniform(0.3, 4.0, n_sources) * t[:, None]
                 + rng.uniform(0, 2 * np.pi, n_sources))
    pts = v[None] + np.tensordot(src, W[:, :, None] * d[:, None, :], axes=1)
    pts += noise * rng.standard_normal(pts.shape)
    return Recording([f"L{j:03d}" for j in range(len(v))], pts, rate, source="dense.trc")


def test_pca_on_a_dense_face_bounds_the_error_against_the_removed_truth():
    truth = dense_face(3000)
    pts = truth.points.copy()
    gaps = {17: (400, 430), 61: (1200, 1290), 291: (2000, 2150), 5: (0, 60), 400: (2950, 3000)}
    for j, (a, b) in gaps.items():
        pts[a:b, j] = np.nan
    filled, rep = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source))
    miss = np.isnan(pts).any(axis=2)
    err = np.linalg.norm(filled.points - truth.points, axis=2)[miss]  # 3-D error, mm
    motion = np.linalg.norm(truth.points - truth.points.mean(axis=0), axis=2)[miss]
    assert np.sqrt(np.mean(err ** 2)) < 0.1 * np.sqrt(3)   # 0.1 mm RMS per coordinate
    assert err.max() < 0.4 * np.sqrt(3)
    # the fill is far better than the marker's mean position (its motion): the test can tell
    assert np.sqrt(np.mean(motion ** 2)) > 10 * np.sqrt(np.mean(err ** 2))
    methods = dict(zip(rep["marker"], rep["fill_method"], strict=True))
    assert {methods[truth.labels[j]] for j in gaps} == {"pca"}
    np.testing.assert_array_equal(filled.points[~miss], truth.points[~miss])


def test_pca_donors_are_the_correlated_markers():
    """With 15 donors out of 467, the fill is as good as with four times as many."""
    from facemotion.ingest import gaps as g

    truth = dense_face(1500, seed=3)
    pts = truth.points.copy()
    pts[600:720, 100] = np.nan
    few, _ = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source), n_donors=15)
    all_, _ = fill_gaps(Recording(truth.labels, pts, truth.rate, truth.source), n_donors=60)
    e_few = np.abs(few.points[600:720, 100] - truth.points[600:720, 100]).max()
    e_all = np.abs(all_.points[600:720, 100] - truth.points[600:720, 100]).max()
    assert e_few < 0.3 and e_all < 0.3
    # the donor score picks markers that explain the gap's marker: better than 15 at random
    rng = np.random.default_rng(0)
    miss = np.isnan(pts).any(axis=2)
    cand = np.array([k for k in range(468) if k != 100])
    score = g._donor_scores(pts[:, 100], ~miss[:, 100], pts[:, cand], ~miss[:, cand])
    top = np.argsort(-score)[:15]
    assert score[top].min() > np.median(score[rng.choice(len(cand), 15, replace=False)])
    with pytest.raises(InputError, match="n_donors"):
        fill_gaps(truth, n_donors=0)
