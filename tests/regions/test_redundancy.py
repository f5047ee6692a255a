"""Copied markers: whole-recording copy, gap fill by copy, and no false alarms on clean data."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ranking.epsilon_rank import epsilon_rank
from facemotion.ranking.routes import rank_markers
from facemotion.regions.redundancy import find_redundant_markers

RATE = 100.0


def recording(S=6, n=20, seed=0):
    """Markers strongly correlated through 4 shared smooth sources, 0.3-0.5 mm noise each."""
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((4, n)) * 4
    D, rs = [], []
    for s in range(S):
        F = int(rng.integers(300, 500))
        t = np.arange(F) / RATE
        f = rng.uniform(1, 6, (4, 3))
        ph = rng.uniform(0, 6, (4, 3))
        src = np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None])  # (F, 4, 3)
        d = np.einsum("fkc,kn->fcn", src, W)
        d += rng.uniform(0.3, 0.5, n) * rng.standard_normal((F, 3, n))
        D.append(d)
        rs.append(np.full(3 * F, s))
    D = np.concatenate(D)
    return D, np.concatenate(rs), [f"m{j}" for j in range(n)]


def to_A(D):
    return D.reshape(-1, D.shape[2])


def test_clean_data_has_no_redundancy():
    for seed in range(3):
        D, rs, labels = recording(seed=seed)
        df = find_redundant_markers(to_A(D), labels, rs, RATE)
        assert len(df) == 0, df


def test_whole_recording_copy_is_one_row_and_drops_epsilon_rank():
    D, rs, labels = recording()
    D[:, :, 7] = D[:, :, 2] + np.array([5.0, -3.0, 1.0])  # copy with a constant offset
    A = to_A(D)
    names = [f"sent{s}" for s in range(6)]
    df = find_redundant_markers(A, labels, rs, RATE, sentence_names=names)
    assert len(df) == 1
    row = df.iloc[0]
    assert (row.marker, row.explained_by) == ("m7", "m2")
    assert row.start_frame == 0 and row.end_frame == D.shape[0]
    assert row.start_s == 0 and row.end_s == pytest.approx(D.shape[0] / RATE)
    assert row.sentences == ",".join(names)
    assert row.coefficient == pytest.approx(1.0) and row.residual_rms_mm < 1e-9
    # the copy (up to its offset, removed by centring each axis) drops the epsilon-rank by one
    Ac = to_A(D - D.mean(axis=0))
    assert epsilon_rank(rank_markers(Ac, labels), [1e-6]).epsilon_rank[0] == 19


def test_partial_copy_found_at_the_right_marker_and_time():
    D, rs, labels = recording(seed=1)
    F = D.shape[0]
    a, b = 500, 560  # a 0.6 s gap of m11 filled by copying m4 (plus offset)
    D[a:b, :, 11] = D[a:b, :, 4] + np.array([2.0, 1.0, 0.0])
    fill = np.zeros((F, 20), dtype=bool)
    fill[a:b, 11] = True
    df = find_redundant_markers(to_A(D), labels, rs, RATE, fill_mask=fill)
    assert len(df) == 1, df
    row = df.iloc[0]
    assert (row.marker, row.explained_by) == ("m11", "m4")
    assert row.start_frame == a and row.end_frame == b
    assert row.start_s == pytest.approx(a / RATE) and row.end_s == pytest.approx(b / RATE)
    # global rank untouched
    assert epsilon_rank(rank_markers(to_A(D), labels), [0.05]).epsilon_rank[0] == 20


def test_short_copy_below_min_duration_is_ignored():
    D, rs, labels = recording(seed=2)
    D[100:110, :, 3] = D[100:110, :, 9]  # 0.1 s
    assert len(find_redundant_markers(to_A(D), labels, rs, RATE, min_duration_s=0.25)) == 0


def test_bad_settings():
    D, rs, labels = recording(S=2)
    with pytest.raises(InputError, match="noise_mm"):
        find_redundant_markers(to_A(D), labels, rs, RATE, noise_mm=0)
    with pytest.raises(InputError, match="rate"):
        find_redundant_markers(to_A(D), labels, rs, -1)
    A = to_A(D).copy()
    A[4, 5] = np.nan
    with pytest.raises(InputError, match="m5"):
        find_redundant_markers(A, labels, rs, RATE)


def test_without_fill_flags_the_later_column_is_the_copy():
    """A file carries no fill flags (all False): the later column is reported as the copy,
    whichever order the pair was scanned in (S1: marker 13 copies 11)."""
    D, rs, labels = recording(seed=3)
    a, b = 200, 290
    D[a:b, :, 13] = D[a:b, :, 11] + np.array([0.0, 4.0, 0.0])
    no_flags = np.zeros((D.shape[0], 20), dtype=bool)
    for mask in (None, no_flags):
        df = find_redundant_markers(to_A(D), labels, rs, RATE, fill_mask=mask)
        assert len(df) == 1, df
        assert (df.iloc[0].marker, df.iloc[0].explained_by) == ("m13", "m11")


def test_noise_estimate_recovers_planted_white_noise():
    """RMS(second difference of velocity) / sqrt(6) is the sd of white positional noise: on
    still markers with planted noise of 0.2 and 0.7 mm the estimate is within 3% of each."""
    from facemotion.regions.redundancy import noise_estimate, velocity_blocks

    rng = np.random.default_rng(5)
    sd = np.array([0.2, 0.7])
    D = rng.standard_normal((2000, 3, 2)) * sd
    vel = velocity_blocks(D, [np.arange(1000), np.arange(1000, 2000)], b=13)
    assert vel.blocks.shape == (2 * 77, 3 * 13, 2)  # 999 velocities: 77 blocks, last padded
    assert list(vel.counts[75:79]) == [13, 11, 13, 13]
    assert np.allclose(noise_estimate(vel, noise_mm=0.5), sd, rtol=0.03)


def test_intervals_touching_at_a_sentence_boundary_merge():
    """A pair's interval that ends on a sentence's last frame and the next one that starts on
    the next sentence's first frame are one; a gap, another pair or a skipped sentence is not."""
    from facemotion.regions.redundancy import merge_across_sentences

    groups = [np.arange(0, 10), np.arange(10, 20), np.arange(20, 30)]
    merged = merge_across_sentences(
        [(0, 1, 5, 10, 0), (0, 1, 10, 14, 1), (0, 2, 5, 10, 0), (0, 2, 11, 20, 1),
         (1, 2, 0, 10, 0), (1, 2, 20, 30, 2)], groups)
    assert merged == [[0, 1, 5, 14, [0, 1]], [0, 2, 5, 10, [0]], [0, 2, 11, 20, [1]],
                      [1, 2, 0, 10, [0]], [1, 2, 20, 30, [2]]]
