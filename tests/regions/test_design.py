"""Marker-set design on the virtual talker: the recommended set against greedy selection, the
interval's stated coverage on fresh sentences, the cross-validation against a direct
computation, the two-stage bootstrap, symmetric sets and the saved file."""

import io
import json
import sys

import numpy as np
import pytest
import scipy.stats

from facemotion.errors import InputError
from facemotion.ingest.displacements import Displacements, build_displacements
from facemotion.io.recording import Recording
from facemotion.regions.design import (
    MarkerSetDesign,
    bootstrap_weights,
    design_markers,
    expanded_alpha,
    mirror_pairs,
    subset_errors,
    symmetric_greedy,
)
from facemotion.regions.optimality import greedy_subset
from facemotion.virtual.talker import simulate_subject


def face_displacements(n_sentences: int, seed: int, **kw) -> Displacements:
    """The virtual talker's face markers, without head motion (so no head fit is needed)."""
    s = simulate_subject("S2a", seed=seed, n_sentences=n_sentences, occlusions=False,
                         head_rotation_deg=0.0, head_translation_mm=0.0, **kw)
    face = [i for i, m in enumerate(s.recordings[0].labels) if m not in s.head_markers]
    recs = [Recording([r.labels[i] for i in face], r.points[:, face], r.rate, r.source)
            for r in s.recordings]
    return build_displacements(recs, s.names)


def sentences_of(d: Displacements, idx) -> Displacements:
    idx = list(idx)
    rows = np.isin(d.row_sentence, idx)
    remap = {s: i for i, s in enumerate(idx)}
    return Displacements(d.A[rows], d.labels, [d.sentences[i] for i in idx],
                         np.array([remap[s] for s in d.row_sentence[rows]]), d.row_frame[rows],
                         d.rate, d.fill_mask[rows[::3]], d.head_residual[rows[::3]], d.neutral)


def mean_error(d: Displacements, ms: MarkerSetDesign) -> float:
    """The set's mean 3-D error on ``d`` with its saved coefficients (an independent path)."""
    main = [d.labels.index(m) for m in ms.selected]
    rest = [d.labels.index(m) for m in ms.coef.columns]
    E = d.A[:, rest] - d.A[:, main] @ ms.coef.to_numpy()
    F = E.shape[0] // 3
    return float(np.sqrt((E.reshape(F, 3, -1) ** 2).sum(axis=1)).mean())


@pytest.fixture(scope="module")
def pilot() -> Displacements:
    return face_displacements(20, seed=1)


def test_recommended_set_is_no_worse_than_greedy(pilot):
    for k in (3, 6):
        ms = design_markers(pilot, k=k, resamples=200)
        G = pilot.A.T @ pilot.A
        greedy = [pilot.labels[j] for j in greedy_subset(G, k)]
        sums, frames = subset_errors(pilot, [pilot.labels.index(m) for m in greedy])
        greedy_err = sums.sum() / (frames.sum() * (pilot.A.shape[1] - k))
        assert ms.expected_error_mm <= greedy_err + 1e-12
        assert set(ms.selected) != set() and len(ms.selected) == k
        # the coefficients are the least-squares fit on all pilot sentences
        main = [pilot.labels.index(m) for m in ms.selected]
        rest = [pilot.labels.index(m) for m in ms.coef.columns]
        X = np.linalg.lstsq(pilot.A[:, main], pilot.A[:, rest], rcond=None)[0]
        np.testing.assert_allclose(ms.coef.to_numpy(), X, atol=1e-9)


def test_k_for_target_and_constraints(pilot):
    ms = design_markers(pilot, target_mm=1.0, resamples=200)
    kft = ms.k_for_target
    assert kft is not None and kft.k is not None and ms.k >= kft.k
    assert kft.error_at_k_mm <= 1.0
    # a looser target needs no more markers
    loose = design_markers(pilot, target_mm=1.5, resamples=200)
    assert loose.k <= ms.k
    forced = design_markers(pilot, k=4, force=["1", "57"], exclude=["40", "38"], resamples=200)
    assert {"1", "57"} <= set(forced.selected) and not {"40", "38"} & set(forced.selected)
    with pytest.raises(InputError, match="force: 3 forced markers do not fit in k = 2"):
        design_markers(pilot, k=2, force=["1", "2", "3"])
    with pytest.raises(InputError, match="no k up to"):
        design_markers(pilot, target_mm=1e-6, resamples=50)


def test_subset_errors_match_a_direct_leave_one_out(pilot):
    sub = [4, 30, 50]
    sums, frames = subset_errors(pilot, sub)
    rest = [j for j in range(pilot.A.shape[1]) if j not in sub]
    s = 7
    test = pilot.row_sentence == s
    X = np.linalg.lstsq(pilot.A[~test][:, sub], pilot.A[~test][:, rest], rcond=None)[0]
    E = pilot.A[test][:, rest] - pilot.A[test][:, sub] @ X
    d = np.linalg.norm(E.reshape(-1, 3, len(rest)), axis=1)   # (F, n - k)
    np.testing.assert_allclose(sums[s, rest], d.sum(axis=0), rtol=1e-9)
    assert frames[s] == d.shape[0] and np.all(sums[:, sub] == 0)


def coverage_consistent(hits: int, n: int, level: float, alpha: float = 0.01) -> bool:
    """Two-sided exact binomial test of ``hits`` covering intervals out of ``n`` against the
    stated coverage ``level``."""
    return scipy.stats.binomtest(hits, n, level).pvalue >= alpha


def test_coverage_rule_rejects_both_sides():
    assert coverage_consistent(14, 16, 0.9)
    assert not coverage_consistent(9, 16, 0.9)       # intervals too narrow
    assert not coverage_consistent(16, 16, 0.5)      # too wide for a 50 % interval
    assert not coverage_consistent(2, 16, 0.5)


@pytest.mark.slow
def test_interval_covers_fresh_sentences_at_its_stated_level():
    """16 pilots of 12 sentences of one session; the truth is each design's mean error on 108
    fresh sentences of the same session (its set, its coefficients)."""
    d = face_displacements(300, seed=3, sentence_duration=(0.8, 1.6))
    fresh = sentences_of(d, range(192, 300))
    level, hits, shrunk = 0.9, 0, 0
    for r in range(16):
        ms = design_markers(sentences_of(d, range(12 * r, 12 * r + 12)), k=4, level=level,
                            max_subsets=0, resamples=1000, seed=r)
        truth = mean_error(fresh, ms)
        assert ms.error_low_mm <= ms.expected_error_mm <= ms.error_high_mm
        hits += ms.error_low_mm <= truth <= ms.error_high_mm
        half = 0.1 * (ms.error_high_mm - ms.error_low_mm)   # a fifth of the width
        shrunk += abs(truth - ms.expected_error_mm) <= half
    assert coverage_consistent(hits, 16, level), hits
    assert not coverage_consistent(shrunk, 16, level), shrunk


def test_two_stage_bootstrap_draws_whole_subjects():
    rng = np.random.default_rng(0)
    groups = ["a"] * 3 + ["b"] * 5 + ["c"] * 2
    W = bootstrap_weights(10, 400, rng, groups)
    assert np.all(W.sum(axis=1) > 0)
    # each resample holds, per drawn copy of a subject, as many sentences as it has
    per = np.stack([W[:, :3].sum(1) / 3, W[:, 3:8].sum(1) / 5, W[:, 8:].sum(1) / 2], axis=1)
    np.testing.assert_array_equal(per, np.round(per))
    assert np.all(per.sum(axis=1) == 3)
    # subjects left out of a resample: some draw no sentence of subject c at all
    assert np.any(per[:, 2] == 0)
    flat = bootstrap_weights(10, 400, rng)
    assert np.all(flat.sum(axis=1) == 10)


def test_subject_resampling_widens_the_interval():
    parts = [face_displacements(6, seed=s) for s in (11, 12, 13)]
    A = np.vstack([p.A for p in parts])
    rs = np.concatenate([p.row_sentence + 6 * i for i, p in enumerate(parts)])
    d = Displacements(A, parts[0].labels, [f"{i}_{s}" for i in range(3) for s in range(6)], rs,
                      np.concatenate([p.row_frame for p in parts]), parts[0].rate,
                      np.vstack([p.fill_mask for p in parts]),
                      np.concatenate([p.head_residual for p in parts]), parts[0].neutral)
    groups = [f"subject{i}" for i in range(3) for _ in range(6)]
    a = design_markers(d, k=4, resamples=500, max_subsets=0)
    b = design_markers(d, k=4, resamples=500, max_subsets=0, groups=groups)
    assert a.selected == b.selected and a.expected_error_mm == b.expected_error_mm
    assert b.settings["resampled"] == "subjects and sentences"
    assert b.subjects == ["subject0", "subject1", "subject2"]
    with pytest.raises(InputError, match="groups: 2 subjects given for 18 sentences"):
        design_markers(d, k=4, groups=["x", "y"])


def test_mirror_pairs_and_symmetric_sets():
    labels = ["LCheek", "RCheek", "Chin", "lip_L", "lip_R", "LeftBrow", "RightBrow", "Nose"]
    assert mirror_pairs(labels) == [("LCheek", "RCheek"), ("Chin",), ("lip_L", "lip_R"),
                                    ("LeftBrow", "RightBrow"), ("Nose",)]
    rng = np.random.default_rng(2)
    A = rng.standard_normal((300, len(labels)))
    chosen = symmetric_greedy(A.T @ A, labels, 3, force=["Chin"], exclude=["Nose"])
    names = {labels[j] for j in chosen}
    assert "Chin" in names and "Nose" not in names
    for a, b in [u for u in mirror_pairs(labels) if len(u) == 2]:
        assert (a in names) == (b in names)


def test_saved_file_round_trip(pilot, tmp_path):
    ms = design_markers(pilot, k=4, resamples=100)
    ms.neutral = pilot.neutral
    path = tmp_path / "set.json"
    ms.save(path)
    d = json.loads(path.read_text())
    assert d["format"] == "facemotion-marker-set" and d["selected"] == ms.selected
    back = MarkerSetDesign.load(path)
    assert back.selected == ms.selected and back.labels == ms.labels
    np.testing.assert_allclose(back.coef.to_numpy(), ms.coef.to_numpy(), atol=1e-8)
    assert back.per_marker["marker"].tolist() == ms.per_marker["marker"].tolist()
    with pytest.raises(FileNotFoundError, match="no such marker-set file"):
        MarkerSetDesign.load(tmp_path / "absent.json")
    (tmp_path / "bad.json").write_text('{"format": "other"}')
    with pytest.raises(InputError, match="not a marker-set file"):
        MarkerSetDesign.load(tmp_path / "bad.json")


def test_expanded_percentile_tail():
    # n = 12, 90 %: z = sqrt(12 / 11) t_{11, 0.95} = 1.04447 * 1.79588 = 1.87575
    assert expanded_alpha(0.9, 12) == pytest.approx(scipy.stats.norm.cdf(-1.87575), rel=1e-4)
    assert expanded_alpha(0.95, 100000) == pytest.approx(0.025, rel=1e-3)   # the plain one
    assert expanded_alpha(0.95, 5) < expanded_alpha(0.95, 20) < 0.025
    assert expanded_alpha(0.95, 1) == pytest.approx(0.025)


def test_an_unreached_target_is_said_and_saved(pilot, tmp_path):
    from facemotion.regions.marker_set import protocol_text

    ms = design_markers(pilot, target_mm=1e-6, resamples=50, on_unreached="largest",
                        max_subsets=0)
    assert ms.settings["target_reached"] is False and ms.k == ms.k_for_target.k_last
    d = ms.to_dict()
    assert d["k_for_target"]["k"] is None and d["k_for_target"]["error_at_k_mm"] is None
    json.dumps(d, allow_nan=False)
    ms.save(tmp_path / "set.json")
    assert MarkerSetDesign.load(tmp_path / "set.json").k_for_target.k is None
    assert "no number of markers reached the target" in protocol_text(ms)
    with pytest.raises(InputError, match="on_unreached"):
        design_markers(pilot, on_unreached="maybe")


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_bars_only_on_a_terminal(monkeypatch, capfd):
    """The long steps of a design (the folds of the cross-validation and of each candidate)
    show a bar on stderr when it is a terminal, and nothing when it is not."""
    small = face_displacements(4, seed=5)
    design_markers(small, target_mm=1.0, resamples=50, progress=True)
    out, err = capfd.readouterr()
    assert out == "" and err == ""                    # pytest's stderr is not a terminal
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    design_markers(small, target_mm=1.0, resamples=50, progress=True)
    shown = term.getvalue()
    assert "cross-validating k:   0%|          | 0/4 " in shown   # one fold a sentence
    assert "scoring candidate sets" in shown
    quiet = _Terminal()
    monkeypatch.setattr(sys, "stderr", quiet)
    design_markers(small, target_mm=1.0, resamples=50)
    assert quiet.getvalue() == ""


def test_the_selection_is_resampled_through_the_gram_matrix(pilot):
    """QR pivots from a factor of A^T A are A's own (56 markers: not a multiple of 3), and
    the selection interval with QR re-selecting holds the estimate."""
    from facemotion.regions.design import QR, _gram_factor, select_subset, selection_interval

    keep = [j for j, m in enumerate(pilot.labels) if m != "57"]
    d = Displacements(pilot.A[:, keep], [pilot.labels[j] for j in keep], pilot.sentences,
                      pilot.row_sentence, pilot.row_frame, pilot.rate, pilot.fill_mask[:, keep],
                      pilot.head_residual, pilot.neutral[keep])
    B = _gram_factor(d.A.T @ d.A)
    assert B.shape == (57, 56)
    np.testing.assert_allclose(B.T @ B, d.A.T @ d.A, rtol=1e-9, atol=1e-6 * np.abs(d.A).max())
    assert select_subset(QR, B, d.labels, 6) == select_subset(QR, d.A, d.labels, 6)
    W = bootstrap_weights(len(d.sentences), 40, np.random.default_rng(0))
    lo, hi = selection_interval(d, QR, 4, (), (), W, 0.9, 0.8, len(d.sentences))
    assert np.isfinite(lo) and lo < 0.8 < hi
