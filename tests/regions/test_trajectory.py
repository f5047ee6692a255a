"""A marker's held-out trajectory (Fig. 9): which marker is drawn, its prediction and note."""

import logging

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.displacements import Displacements
from facemotion.ranking.routes import rank_markers
from facemotion.regions.trajectory import heldout_trajectory, trajectory_marker


def sentences(seed=0, n=6, frames=(40, 30), rate=100.0):
    """Sentences of n markers driven by 2 sources; marker M5 moves 3x more in the second."""
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((2, n))
    parts = [np.cumsum(rng.standard_normal((3 * f, 2)), axis=0) @ W
             + 0.1 * rng.standard_normal((3 * f, n)) for f in frames]
    parts[1][:, 5] *= 3.0
    A = np.concatenate(parts)
    row_sentence = np.concatenate([np.full(3 * f, s) for s, f in enumerate(frames)])
    row_frame = np.concatenate([np.repeat(np.arange(f), 3) for f in frames])
    F = A.shape[0] // 3
    return Displacements(A, [f"M{j}" for j in range(n)], ["s31", "s32"], row_sentence,
                         row_frame, rate, np.zeros((F, n), bool), np.zeros(F), np.zeros((n, 3)))


def test_the_requested_marker_is_predicted_from_the_main_markers():
    """The model of a secondary marker is B_m x with x the least-squares fit of the marker on
    the main markers over the training data (eq. 4); time, table and no note."""
    train, held = sentences(seed=1, frames=(200, 200)), sentences()
    ranking = rank_markers(train.A, train.labels)
    secondary = ranking.labels_in_order[3]
    traj = heldout_trajectory(ranking, 2, held, requested=secondary, sentence_number=1)
    main = [train.labels.index(m) for m in ranking.labels_in_order[:2]]
    j = train.labels.index(secondary)
    x = np.linalg.lstsq(train.A[:, main], train.A[:, j], rcond=None)[0]
    B = held.A[:120]  # sentence s31: 40 frames
    np.testing.assert_allclose(traj.model, (B[:, main] @ x).reshape(-1, 3), rtol=1e-8,
                               atol=1e-8)
    np.testing.assert_array_equal(traj.measured, B[:, j].reshape(-1, 3))
    assert (traj.marker, traj.sentence, traj.in_basis, traj.note) == (secondary, "s31", False,
                                                                     None)
    np.testing.assert_allclose(traj.time_s, np.arange(40) / 100.0)
    table = traj.table()
    assert list(table["axis"]) == ["x", "y", "z"] and set(table["requested_marker"]) == {secondary}
    np.testing.assert_allclose(table["max_abs_error_mm"],
                               np.abs(traj.measured - traj.model).max(axis=0))


def test_an_absent_marker_falls_back_to_the_secondary_marker_that_moves_most(caplog):
    one = sentences().subset([1])
    with caplog.at_level(logging.WARNING, logger="facemotion"):
        assert trajectory_marker(one, ["M0", "M1"], "56") == "M5"
        expected = max(["M1", "M2", "M3", "M4"],
                       key=lambda m: np.sum(one.A[:, one.labels.index(m)] ** 2))
        assert trajectory_marker(one, ["M0", "M5"], None) == expected
    messages = [r.getMessage() for r in caplog.records]
    assert "'56' is not in this dataset: drawing M5, the secondary marker" in messages[0]
    assert messages[1].startswith("eval.trajectory_marker None not set: drawing ")


@pytest.mark.parametrize("requested,note", [
    ("56", "marker 56 requested, not in this dataset"),
    (None, "no marker requested: the secondary marker that moves most"),
])
def test_the_note_says_why_another_marker_is_drawn(requested, note):
    held = sentences()
    ranking = rank_markers(sentences(seed=2, frames=(200, 200)).A, held.labels)
    traj = heldout_trajectory(ranking, 2, held, requested=requested, sentence_number=2)
    assert traj.note == note and not traj.in_basis
    assert set(traj.table()["requested_marker"]) == {requested or ""}


def test_a_main_marker_is_copied_by_the_model():
    held = sentences()
    ranking = rank_markers(held.A, held.labels)
    traj = heldout_trajectory(ranking, 2, held, requested=ranking.labels_in_order[0],
                              sentence_number=2)
    assert traj.in_basis and np.array_equal(traj.model, traj.measured)
    assert (traj.table()["max_abs_error_mm"] == 0).all()


def test_sentences_count_from_1_and_the_old_0_based_argument_warns():
    held = sentences()
    ranking = rank_markers(sentences(seed=2, frames=(200, 200)).A, held.labels)
    assert heldout_trajectory(ranking, 2, held, requested="M5").sentence == "s31"
    second = heldout_trajectory(ranking, 2, held, requested="M5", sentence_number=2)
    assert second.sentence == "s32"
    with pytest.warns(DeprecationWarning, match=r"counts held-out sentences from 0"):
        old = heldout_trajectory(ranking, 2, held, 1, "M5")
    np.testing.assert_array_equal(old.model, second.model)
    with pytest.raises(InputError, match=r"sentence_number: held-out sentence 3 out of range "
                                         r"for 2 held-out sentence\(s\) \(counting from 1\)"):
        heldout_trajectory(ranking, 2, held, sentence_number=3)
    with pytest.raises(InputError, match="sentence_number: held-out sentence 0 out of range"):
        heldout_trajectory(ranking, 2, held, sentence_number=0)
    with pytest.raises(InputError, match="give one of them"):
        heldout_trajectory(ranking, 2, held, 0, sentence_number=1)
