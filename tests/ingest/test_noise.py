"""The noise estimate against planted noise (the virtual talker's, white noise on smooth
motion), and the noise tolerance against the 2-norm of simulated noise matrices."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.noise import high_frequency_noise, window_frames
from facemotion.ranking.epsilon_rank import noise_epsilon
from facemotion.virtual.talker import NOISE_PER_AXIS_MM, simulate_subject


def talker_points(noise_mm):
    s = simulate_subject("S2a", seed=0, n_sentences=4, head_rotation_deg=0.0,
                         head_translation_mm=0.0, occlusions=False, noise_mm=noise_mm)
    pts = np.concatenate([r.points for r in s.recordings])
    ids = np.concatenate([np.full(r.points.shape[0], i) for i, r in enumerate(s.recordings)])
    return pts, ids


@pytest.mark.parametrize("factor", [1.0, 2.0])
def test_recovers_the_virtual_talkers_planted_noise(factor):
    sigma = NOISE_PER_AXIS_MM * factor
    pts, ids = talker_points(sigma * np.sqrt(3.0))       # noise_mm is the 3-D RMS
    est, w = high_frequency_noise(pts, ids, 120.0)
    assert w == 7
    assert est == pytest.approx(sigma, rel=0.05)
    # two-sided: the other level is rejected by the same tolerance
    other = NOISE_PER_AXIS_MM * (3.0 - factor)
    assert est != pytest.approx(other, rel=0.05)


def test_smooth_speech_motion_alone_is_not_taken_for_noise():
    pts, ids = talker_points(0.0)
    est, _ = high_frequency_noise(pts, ids, 120.0)
    assert est < 0.1 * NOISE_PER_AXIS_MM


def test_white_noise_on_sines_at_a_low_rate():
    rng = np.random.default_rng(0)
    t = np.arange(3000) / 25.0                      # GRID's 25 frames/s
    smooth = 2.0 * np.sin(2 * np.pi * 0.7 * t)[:, None, None] * np.ones((1, 8, 3))
    pts = smooth + 0.3 * rng.standard_normal(smooth.shape)
    filled = np.zeros((3000, 8), dtype=bool)
    filled[100:200] = True
    est, w = high_frequency_noise(pts, np.zeros(3000, int), 25.0, filled)
    assert w == 5
    assert est == pytest.approx(0.3, rel=0.05)


def test_windows():
    assert [window_frames(r) for r in (25, 60, 100, 120, 240)] == [5, 5, 5, 7, 13]


def test_noise_tolerance_is_the_norm_of_a_noise_matrix():
    rng = np.random.default_rng(0)
    rows, n, sigma = 3000, 40, 0.2
    norms = [np.linalg.norm(sigma * rng.standard_normal((rows, n)), 2) for _ in range(5)]
    assert np.mean(norms) == pytest.approx(noise_epsilon(sigma, rows, n), rel=0.02)
    # per-coordinate normalisation divides by sqrt(rows)
    assert noise_epsilon(sigma, rows, n, "per_coordinate") == pytest.approx(
        noise_epsilon(sigma, rows, n) / np.sqrt(rows))
    with pytest.raises(InputError, match="noise level"):
        noise_epsilon(0.0, rows, n)
