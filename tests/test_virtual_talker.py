"""The virtual talker (built-in subjects): deterministic, paper-like, honest ground truth.

References are independent of the code under test: scipy's pivoted QR on a displacement
matrix built here from the ground-truth head motion (not the package's head alignment).
"""

import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.synth import (
    NOISE_PER_AXIS_MM,
    influence_fields,
    make_talker,
    simulate_subject,
)

FACE = [str(i) for i in range(1, 58)]
PIVOT = np.array([0.0, -90.0, -80.0])


def head_frame(rec, head_motion):
    """Undo the planted head motion with the ground truth (independent of head_motion.py)."""
    R = Rotation.from_rotvec(head_motion[:, :3]).as_matrix()
    p = rec.points - PIVOT - head_motion[:, None, 3:]
    return np.einsum("fji,fnj->fni", R, p) + PIVOT


def truth_head_motion(subj, s):
    frames = subj.truth["sentence_frames"]
    start = int(np.sum(frames[:s]))
    return subj.truth["head_motion"][start:start + frames[s]]


def displacement_matrix(subj, sentences):
    blocks = []
    idx = [subj.recordings[0].labels.index(m) for m in FACE]
    for s in sentences:
        p = head_frame(subj.recordings[s], truth_head_motion(subj, s))[:, idx]
        d = p - p[0]
        blocks.append(d.transpose(0, 2, 1).reshape(-1, len(FACE)))   # row 3f+c, marker column
    return np.vstack(blocks)


def ranking(A):
    R, P = scipy.linalg.qr(A, mode="r", pivoting=True)
    r_rms = np.abs(np.diag(R)) / np.sqrt(A.shape[0])
    return [FACE[p] for p in P], r_rms


@pytest.fixture(scope="module")
def subjects():
    return {d: simulate_subject(d, seed=i + 1, occlusions=False)
            for i, d in enumerate(["S1", "S2a", "S2b"])}


def test_deterministic_by_seed():
    a = simulate_subject("S2a", seed=5, n_sentences=3, occlusions=False)
    b = simulate_subject("S2a", seed=5, n_sentences=3, occlusions=False)
    c = simulate_subject("S2a", seed=6, n_sentences=3, occlusions=False)
    for ra, rb in zip(a.recordings, b.recordings, strict=True):
        assert np.array_equal(ra.points, rb.points)
    assert not np.array_equal(a.recordings[0].points[:10], c.recordings[0].points[:10])


def test_layout_keeps_the_papers_marker_numbers():
    t = make_talker(0)
    pos = dict(zip(t.labels, t.neutral, strict=True))
    assert pos["2"][0] < 0 < pos["6"][0]            # right brow on the talker's right (-x)
    assert pos["11"][0] < 0 < pos["13"][0]          # eyelids
    assert pos["38"][0] < pos["36"][0] < pos["34"][0]  # right corner, upper centre, left corner
    assert pos["40"][1] < pos["36"][1]              # lower lip below the upper lip
    assert pos["56"][1] == min(p[1] for p in t.neutral)  # chin lowest
    assert pos["2"][1] > pos["11"][1] > pos["36"][1]     # brows above eyes above mouth


def test_s1_marker_13_copies_11_exactly_where_filled(subjects):
    s1 = subjects["S1"]
    labels = s1.recordings[0].labels
    i11, i13 = labels.index("11"), labels.index("13")
    neutral = s1.truth["neutral"]
    offset = neutral[i13] - neutral[i11]
    n_filled = n_total = 0
    for s, rec in enumerate(s1.recordings):
        p = head_frame(rec, truth_head_motion(s1, s))
        mask = rec.filled[:, i13]
        assert not rec.filled[:, [j for j in range(len(labels)) if j != i13]].any()
        if mask.any():
            assert np.max(np.abs(p[mask, i13] - p[mask, i11] - offset)) < 1e-9
        if (~mask).any():   # where measured, 13 is not a copy
            assert np.sqrt(np.mean((p[~mask, i13] - p[~mask, i11] - offset) ** 2)) > 0.2
        n_filled += mask.sum()
        n_total += mask.size
    assert 0.85 < n_filled / n_total < 0.97


def test_epsilon_rank_and_first_pivots_are_paper_like(subjects):
    order, r = ranking(displacement_matrix(subjects["S1"], range(30)))
    assert int(np.sum(r > 0.5)) == 56
    assert order[-1] in {"11", "13"} and r[-1] < 0.35   # QR cannot tell copy from source
    for name, sl in (("S2a", range(30)), ("S2b", range(30)), ("S2a", range(20, 50))):
        order, r = ranking(displacement_matrix(subjects[name], sl))
        assert int(np.sum(r > 0.5)) == 57, name
        assert r[-1] > 0.55, name
        assert order[0] in {"40", "55", "56", "57"}, name      # lower lip or jaw first
        # a marker at each lip corner (the corner itself or its lateral neighbour) early
        assert {"34", "33"} & set(order[:8]) and {"38", "32"} & set(order[:8]), name
        assert "36" in order[:6], name                         # upper lip
        assert {"2", "6"} & set(order[:16]), name              # a brow
        assert {"11", "13"} & set(order[:16]), name            # an eyelid


def test_noise_and_head_motion_are_as_documented(subjects):
    s = subjects["S2a"]
    rec = s.recordings[0]
    hm = truth_head_motion(s, 0)
    deg = np.rad2deg(np.linalg.norm(hm[:, :3], axis=1))
    assert 0.5 < deg.max() < 10 and 0.5 < np.abs(hm[:, 3:]).max() < 15
    # the head band is rigid: after undoing the true head motion only noise is left
    p = head_frame(rec, hm)
    band = [rec.labels.index(h) for h in s.head_markers]
    resid = p[:, band] - s.truth["neutral"][band]
    assert abs(resid.std() - NOISE_PER_AXIS_MM) < 0.03
    # sentences start at rest: the first frames differ from the neutral by noise only
    face = p[0, :57] - s.truth["neutral"][:57]
    assert np.sqrt(np.mean(face**2)) < 3 * NOISE_PER_AXIS_MM


def test_fields_have_positive_and_negative_lobes():
    D = influence_fields(make_talker(0).neutral)
    assert D.shape == (11, 57, 3)
    jaw_y = D[0, :, 1]
    assert jaw_y.min() < -5 and jaw_y.max() > 0.2    # chin down, cheeks slightly up


def test_bad_design_and_sizes():
    with pytest.raises(InputError, match="design 'S9' unknown"):
        simulate_subject("S9")
    with pytest.raises(InputError, match="n_sentences"):
        simulate_subject("S", n_sentences=None)
    with pytest.raises(InputError, match="sentence_duration"):
        simulate_subject("S", n_sentences=2, sentence_duration=(2.0, 1.0))
