"""The virtual talker (facemotion.synth) against its planted ground truth and the paper's design.

The references are independent of the package's analysis code: the head frame comes either
from the planted head motion or from a small Kabsch fit of the head band written here, and the
ranking from scipy's pivoted QR on a displacement matrix built here (rows frame-major: row
3f + c is axis c of frame f; one column per face marker '1'..'57').
"""

import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.recording import Recording
from facemotion.synth import (
    HEAD_PIVOT,
    NOISE_3D_RMS_MM,
    NOISE_PER_AXIS_MM,
    SOURCES,
    influence_fields,
    marker_layout,
    simulate_subject,
    truth_to_npz,
)

FACE = [str(i) for i in range(1, 58)]
HEAD = [f"H{i}" for i in range(1, 7)]
STUDY_SEEDS = {"S1": 1, "S2a": 2, "S2b": 3}       # config/subjects.tsv


def sentence_rows(subj, s, key):
    frames = subj.truth["sentence_frames"]
    start = int(np.sum(frames[:s]))
    return subj.truth[key][start:start + frames[s]]


def undo_head_motion(points, hm):
    """q = R^T (p - c - T) + c with R from the planted rotation vector (scipy, not synth)."""
    R = Rotation.from_rotvec(hm[:, :3]).as_matrix()
    return np.einsum("fji,fnj->fni", R, points - HEAD_PIVOT - hm[:, None, 3:]) + HEAD_PIVOT


def kabsch_head_frame(rec, reference):
    """Fit the head band of every frame onto the reference (Kabsch 1976) and move all markers."""
    idx = [rec.labels.index(h) for h in HEAD]
    out = np.empty_like(rec.points)
    yc = reference.mean(axis=0)
    for f in range(rec.n_frames):
        X = rec.points[f, idx]
        xc = X.mean(axis=0)
        U, _, Vt = np.linalg.svd((X - xc).T @ (reference - yc))
        d = np.sign(np.linalg.det(Vt.T @ U.T))
        R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
        out[f] = (rec.points[f] - xc) @ R.T + yc
    return out


def displacement_matrix(subj, sentences, kabsch=False):
    face = [subj.recordings[0].labels.index(m) for m in FACE]
    band = subj.truth["neutral"][-6:]
    blocks = []
    for s in sentences:
        rec = subj.recordings[s]
        p = (kabsch_head_frame(rec, band) if kabsch
             else undo_head_motion(rec.points, sentence_rows(subj, s, "head_motion")))[:, face]
        d = p - p[0]
        blocks.append(d.transpose(0, 2, 1).reshape(-1, len(FACE)))
    return np.vstack(blocks)


def ranking(A):
    R, P = scipy.linalg.qr(A, mode="r", pivoting=True)
    return [FACE[p] for p in P], np.abs(np.diag(R)) / np.sqrt(A.shape[0])


@pytest.fixture(scope="module")
def subjects():
    return {d: simulate_subject(d, seed=s, occlusions=False) for d, s in STUDY_SEEDS.items()}


def test_deterministic_by_seed():
    a = simulate_subject("S2a", seed=5, n_sentences=3, occlusions=False)
    b = simulate_subject("S2a", seed=5, n_sentences=3, occlusions=False)
    c = simulate_subject("S2a", seed=6, n_sentences=3, occlusions=False)
    for ra, rb in zip(a.recordings, b.recordings, strict=True):
        assert np.array_equal(ra.points, rb.points) and np.array_equal(ra.filled, rb.filled)
    for key in a.truth:
        assert np.array_equal(a.truth[key], b.truth[key]), key
    assert not np.array_equal(a.recordings[0].points[:10], c.recordings[0].points[:10])
    assert not np.array_equal(a.truth["source_courses"][:100], c.truth["source_courses"][:100])
    # another talker changes the face itself
    d = simulate_subject("S2a", seed=5, n_sentences=3, talker_seed=9, occlusions=False)
    assert not np.allclose(a.truth["neutral"], d.truth["neutral"])


def test_layout_geometry_and_the_papers_numbers():
    labels, neutral, regions = marker_layout()
    assert labels == FACE + HEAD and neutral.shape == (63, 3)
    pos = dict(zip(labels, neutral, strict=True))
    assert pos["2"][0] < 0 < pos["6"][0]                      # x from right to left
    assert pos["11"][0] < 0 < pos["13"][0]
    assert pos["38"][0] < pos["36"][0] < pos["34"][0]
    assert pos["40"][1] < pos["36"][1] < pos["11"][1] < pos["2"][1]   # y up
    assert pos["56"][1] == neutral[:57, 1].min()               # the chin is lowest
    face = neutral[:57]
    assert 120 < np.ptp(neutral[:, 0]) < 170 and 150 < np.ptp(neutral[:, 1]) < 220
    assert pos["17"][2] == face[:, 2].max()                    # nose tip most forward (z)
    assert np.ptp(face[:, 2]) > 30                             # a curved surface
    # roughly but not exactly symmetric: 2 mirrors 6 within a few mm, not exactly
    mirror = pos["6"] * [-1, 1, 1] - pos["2"]
    assert 0 < np.linalg.norm(mirror) < 10
    # head band: six markers round the forehead, not collinear
    band = neutral[57:]
    assert np.linalg.svd(band - band.mean(0), compute_uv=False)[1] > 20
    assert band[:, 1].min() > face[:, 1].mean()
    assert sorted(sum(regions.values(), [])) == sorted(labels)
    assert {"40", "36", "34", "38"} <= set(regions["lips"])
    # S2b is the same talker with markers re-placed by a few mm
    _, n2b, _ = marker_layout(design="S2b")
    shift = np.linalg.norm(n2b[:57, :2] - face[:, :2], axis=1)
    assert 1.0 < np.median(shift) < 5.0 and np.array_equal(n2b[57:], band)


def test_influence_fields_have_lobes_of_both_signs():
    _, neutral, _ = marker_layout()
    D = influence_fields(neutral[:57])
    assert D.shape == (len(SOURCES), 57, 3)
    i = {m: FACE.index(m) for m in FACE}
    jaw = D[SOURCES.index("jaw_open")]
    assert jaw[i["56"], 1] < -7 and jaw[i["40"], 1] < -5       # chin and lower lip down
    assert abs(jaw[i["2"]]).max() < 0.05                       # the brows do not move
    assert jaw[:, 1].max() > 0.2                               # cheeks rise a little
    low = D[SOURCES.index("lower_lip_depression")]
    assert low[i["40"], 1] < -2.5 and low[:, 1].max() > 0.2    # lower lip down, cheeks up
    lc = D[SOURCES.index("left_corner_retraction")]
    assert lc[i["34"], 0] > 3 and abs(lc[i["38"], 0]) < 0.5    # the left corner, to the left
    blink = D[SOURCES.index("right_blink")]
    assert -9 < blink[i["11"], 1] < -5 and abs(blink[i["13"], 1]) < 0.1


def test_sources_at_speech_rates_smooth_and_starting_at_rest(subjects):
    subj = subjects["S2a"]
    rate = float(subj.truth["rate"])
    frames = subj.truth["sentence_frames"]
    assert frames.min() >= 1.5 * rate and frames.max() <= 4.0 * rate + 1
    jaw_peaks = []
    for s in range(10):
        c = sentence_rows(subj, s, "source_courses")
        assert np.allclose(c[0], 0.0, atol=1e-12)                 # rest at t = 0
        assert np.abs(np.diff(c, axis=0)).max() < 0.2             # smooth at 120 Hz
        jaw = c[:, SOURCES.index("jaw_open")]
        peaks = np.sum((jaw[1:-1] > jaw[:-2]) & (jaw[1:-1] >= jaw[2:]) & (jaw[1:-1] > 0.2))
        jaw_peaks.append(peaks / (len(c) / rate))
    assert 3.0 < np.mean(jaw_peaks) < 7.0                          # syllables per second
    D = subj.truth["fields"]
    courses = subj.truth["source_courses"]
    chin = courses @ D[:, FACE.index("56"), 1]
    assert 8 < -chin.min() < 20                                     # jaw opening 10-15 mm
    lid = courses @ D[:, FACE.index("11"), 1]
    assert 4.5 < -lid.min() < 10                                    # blinks 5-8 mm


def test_s1_marker_13_copies_11_where_filled(subjects):
    s1 = subjects["S1"]
    labels = s1.recordings[0].labels
    i11, i13 = labels.index("11"), labels.index("13")
    offset = s1.truth["neutral"][i13] - s1.truth["neutral"][i11]
    n_filled = n_total = 0
    for s, rec in enumerate(s1.recordings):
        mask = rec.filled[:, i13]
        assert np.array_equal(mask, sentence_rows(s1, s, "filled_13"))
        assert np.array_equal(rec.filled, sentence_rows(s1, s, "filled"))
        assert not np.delete(rec.filled, i13, axis=1).any()      # only 13 is filled
        q = undo_head_motion(rec.points, sentence_rows(s1, s, "head_motion"))
        if mask.any():
            assert np.max(np.abs(q[mask, i13] - q[mask, i11] - offset)) < 1e-9
        if (~mask).any():                                          # measured: not a copy
            assert np.sqrt(np.mean((q[~mask, i13] - q[~mask, i11] - offset) ** 2)) > 0.3
        n_filled += mask.sum()
        n_total += mask.size
    assert 0.85 < n_filled / n_total < 0.97
    # the other designs are clean
    for d in ("S2a", "S2b"):
        assert not any(r.filled.any() for r in subjects[d].recordings)


def test_s1_epsilon_rank_56_with_13_below_tolerance(subjects):
    for sentences in (range(30), range(40)):
        order, r = ranking(displacement_matrix(subjects["S1"], sentences))
        assert int(np.sum(r > 0.5)) == 56
        assert order[-1] == "13" and r[-1] < 0.35
        assert r[-2] > 0.6
        assert order[0] in {"40", "56"}


@pytest.mark.parametrize("design", ["S2a", "S2b"])
def test_s2_epsilon_rank_57_and_paper_like_first_pivots(subjects, design):
    for sentences in (range(30), range(50), range(20, 50)):
        order, r = ranking(displacement_matrix(subjects[design], sentences))
        assert int(np.sum(r > 0.5)) == 57, (design, sentences)
        assert r[-1] > 0.6, (design, sentences)
        assert order[0] in {"40", "56"}                            # lower lip or chin first
        assert {"34", "38"} <= set(order[:6])                      # both lip corners early
        assert "36" in order[:10]                                  # upper lip
        assert {"2", "6"} & set(order[:10])                        # a brow
        assert {"11", "13"} & set(order[:10])                      # an eyelid


def test_ranking_survives_a_kabsch_head_alignment(subjects):
    """The package's route (fit the head band per frame) gives the same rank results."""
    order, r = ranking(displacement_matrix(subjects["S1"], range(30), kabsch=True))
    assert int(np.sum(r > 0.5)) == 56 and order[-1] == "13" and r[-1] < 0.35
    order, r = ranking(displacement_matrix(subjects["S2a"], range(30), kabsch=True))
    assert int(np.sum(r > 0.5)) == 57 and r[-1] > 0.6 and order[0] in {"40", "56"}


def test_head_motion_and_noise_are_as_documented(subjects):
    subj = subjects["S2a"]
    hm = subj.truth["head_motion"]
    deg = np.rad2deg(np.linalg.norm(hm[:, :3], axis=1))
    assert 1.0 < deg.max() < 12 and 0.5 < np.median(deg) < 5        # a few degrees
    assert 1.0 < np.abs(hm[:, 3:]).max() < 15                      # a few millimetres
    for s in range(10):                                          # smooth between frames
        step = np.abs(np.diff(sentence_rows(subj, s, "head_motion"), axis=0)).max(axis=0)
        assert step[:3].max() < np.deg2rad(0.1) and step[3:].max() < 0.25
    band = [subj.recordings[0].labels.index(h) for h in HEAD]
    resid = []
    for s in range(10):
        rec = subj.recordings[s]
        q = undo_head_motion(rec.points, sentence_rows(subj, s, "head_motion"))
        resid.append(q[:, band] - subj.truth["neutral"][band])   # rigid band: noise only
        # sentences start at rest: the first frame is the neutral face plus noise
        first = q[0, :57] - subj.truth["neutral"][:57]
        assert np.sqrt(np.mean(np.sum(first**2, axis=-1))) < 2 * NOISE_3D_RMS_MM
    resid = np.concatenate(resid).reshape(-1, 3)
    assert abs(resid.std(axis=0) - NOISE_PER_AXIS_MM).max() < 0.02     # per coordinate
    assert abs(np.sqrt(np.mean(np.sum(resid**2, axis=1))) - NOISE_3D_RMS_MM) < 0.02  # 3-D
    assert abs(resid.mean()) < 0.01
    # and the noise-free face model plus noise explains the face up to the skin motion
    rec = subj.recordings[0]
    q = undo_head_motion(rec.points, sentence_rows(subj, 0, "head_motion"))[:, :57]
    model = subj.truth["neutral"][:57] + np.einsum(
        "fk,knc->fnc", sentence_rows(subj, 0, "source_courses"), subj.truth["fields"])
    local = np.sqrt(np.mean((q - model) ** 2))
    assert 0.5 < local < 1.0                  # skin motion ~0.6 mm and noise 0.29 mm per axis


def test_smoke_size_generic_design_and_recordings(tmp_path):
    subj = simulate_subject("S", seed=0, n_sentences=4, sentence_duration=(0.5, 1.0),
                            rate=60.0, occlusions=False)
    assert subj.names == ["S_s01", "S_s02", "S_s03", "S_s04"]
    assert subj.head_markers == HEAD
    for rec in subj.recordings:
        assert isinstance(rec, Recording) and rec.rate == 60.0
        assert 30 <= rec.n_frames <= 60 and rec.labels == FACE + HEAD
        assert np.isfinite(rec.points).all() and not rec.filled.any()
    path = tmp_path / "truth.npz"
    truth_to_npz(subj, path)
    with np.load(path) as z:
        assert np.array_equal(z["head_motion"], subj.truth["head_motion"])
        assert int(z["sentence_frames"].sum()) == sum(r.n_frames for r in subj.recordings)
    assert [p.name for p in tmp_path.iterdir()] == ["truth.npz"]


def test_speed_of_a_full_session():
    import time

    t0 = time.perf_counter()
    simulate_subject("S2a", seed=0)
    assert time.perf_counter() - t0 < 2.0


def test_bad_settings_name_the_setting():
    with pytest.raises(InputError, match="design 'S9' unknown"):
        simulate_subject("S9")
    with pytest.raises(InputError, match="design 'S3' unknown"):
        marker_layout(design="S3")
    with pytest.raises(InputError, match="n_sentences"):
        simulate_subject("S")
    with pytest.raises(InputError, match="n_sentences"):
        simulate_subject("S2a", n_sentences=0)
    with pytest.raises(InputError, match="sentence_duration"):
        simulate_subject("S", n_sentences=2, sentence_duration=(2.0, 1.0))
    with pytest.raises(InputError, match="rate"):
        simulate_subject("S", n_sentences=2, rate=0.0)
    with pytest.raises(InputError, match="fill_fraction"):
        simulate_subject("S1", fill_fraction=1.5)


def test_occlusions_are_missing_samples_that_survive_c3d(tmp_path):
    """Occluded samples are NaN exactly where the truth says, never in 11/13 or the first
    frames; written to C3D as invalid samples they read back as NaN; everything else is the
    same as without occlusions (a separate random stream)."""
    from facemotion.readers import read_c3d, write_c3d

    subj = simulate_subject("S2a", seed=4, n_sentences=12)
    clean = simulate_subject("S2a", seed=4, n_sentences=12, occlusions=False)
    missing = subj.truth["missing"]
    assert missing.any()
    points = np.concatenate([r.points for r in subj.recordings])
    assert np.array_equal(~np.isfinite(points).all(axis=2), missing)
    labels = subj.recordings[0].labels
    assert not missing[:, [labels.index("11"), labels.index("13")]].any()
    assert np.array_equal(points[~missing], np.concatenate([r.points for r in
                                                            clean.recordings])[~missing])
    start = 0
    for rec in subj.recordings:
        assert not missing[start:start + 10].any()
        start += rec.n_frames
    k = int(np.flatnonzero([~np.isfinite(r.points).all() for r in subj.recordings])[0])
    write_c3d(tmp_path / "s.c3d", subj.recordings[k])
    back = read_c3d(tmp_path / "s.c3d")
    assert np.array_equal(np.isnan(back.points), np.isnan(subj.recordings[k].points))
