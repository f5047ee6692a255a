"""The cross-subject consensus against a hand-made pooling (planted truth: subject B is subject
B's data under renamed labels, mapped back by its label map), and bad label maps refused in one
line naming the file and line."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.displacements import Displacements
from facemotion.regions.consensus import (
    SubjectPilot,
    common_labels,
    consensus_design,
    read_subject_label_map,
)
from facemotion.regions.design import design_markers, subset_errors
from tests.regions.test_design import face_displacements


def renamed(d: Displacements, names: list[str]) -> Displacements:
    return Displacements(d.A, names, d.sentences, d.row_sentence, d.row_frame, d.rate,
                         d.fill_mask, d.head_residual, d.neutral)


def by_hand(a: Displacements, b: Displacements, keep: list[str]) -> Displacements:
    """A and B stacked on the markers ``keep`` (shared labels), sentences A's then B's."""
    ca = [a.labels.index(m) for m in keep]
    cb = [b.labels.index(m) for m in keep]
    S = len(a.sentences)
    return Displacements(
        np.vstack([a.A[:, ca], b.A[:, cb]]), keep,
        [f"A/{s}" for s in a.sentences] + [f"B/{s}" for s in b.sentences],
        np.concatenate([a.row_sentence, b.row_sentence + S]),
        np.concatenate([a.row_frame, b.row_frame]), a.rate,
        np.vstack([a.fill_mask[:, ca], b.fill_mask[:, cb]]),
        np.concatenate([a.head_residual, b.head_residual]), a.neutral[ca])


@pytest.fixture(scope="module")
def subjects():
    return face_displacements(6, seed=21), face_displacements(7, seed=22)


def test_consensus_equals_the_design_of_the_subjects_pooled_by_hand(subjects, tmp_path):
    a, b_true = subjects
    # subject B lacks marker "57" and calls every other marker "B<label>"
    keep = [m for m in b_true.labels if m != "57"]
    cols = [b_true.labels.index(m) for m in keep]
    b_true = Displacements(b_true.A[:, cols], keep, b_true.sentences, b_true.row_sentence,
                           b_true.row_frame, b_true.rate, b_true.fill_mask[:, cols],
                           b_true.head_residual, b_true.neutral[cols])
    b = renamed(b_true, [f"B{m}" for m in keep])
    table = tmp_path / "B.tsv"
    table.write_text("label\tcommon\n" + "".join(f"B{m}\t{m}\n" for m in keep))
    lm = read_subject_label_map(table)
    own_a = design_markers(a, k=3, resamples=100)
    own_b = design_markers(b, k=3, resamples=100)
    pilots = [SubjectPilot("A", "A", a, common_labels(a.labels, None), own_a.selected,
                           own_a.expected_error_mm),
              SubjectPilot("B", "B", b, common_labels(b.labels, lm), own_b.selected,
                           own_b.expected_error_mm)]
    con = consensus_design(pilots, target_mm=1.0, resamples=300, seed=4)
    pooled = by_hand(a, b_true, keep)
    groups = ["A"] * 6 + ["B"] * 7
    ref = design_markers(pooled, target_mm=1.0, resamples=300, seed=4, groups=groups)
    ms = con.design
    assert ms.selected == ref.selected and ms.k == ref.k
    assert ms.k_for_target == ref.k_for_target
    assert (ms.expected_error_mm, ms.error_low_mm, ms.error_high_mm) == \
        (ref.expected_error_mm, ref.error_low_mm, ref.error_high_mm)
    assert ms.settings["resampled"] == "subjects and sentences"
    assert ms.settings["not_in_every_subject"] == ["57"]
    # the marker table: every common marker, B's own label beside it, and who placed it
    t = con.markers.set_index("marker")
    assert t.loc["57", "role"] == "not in every subject"
    assert t.loc["12", "subject_labels"] == "A:12,B:B12"
    for m in keep:
        hand = (m in own_a.selected) + (f"B{m}" in own_b.selected)
        assert t.loc[m, "placed_by_subjects"] == hand
    # per subject: the consensus set's held-out error on that subject's sentences
    sums, frames = subset_errors(pooled, [keep.index(m) for m in ref.selected])
    rest = len(keep) - ref.k
    for s, rows in (("A", slice(0, 6)), ("B", slice(6, 13))):
        got = con.subjects.set_index("subject").loc[s, "consensus_error_mm"]
        assert got == pytest.approx(sums[rows].sum() / (frames[rows].sum() * rest), rel=1e-12)
    # the pooled error is the subjects' errors weighted by their frames, not one of them
    e = con.subjects["consensus_error_mm"].to_numpy()
    assert e.min() < ms.expected_error_mm < e.max()


@pytest.mark.parametrize("text, message", [
    ("label\tcommon\nx\t1\nx\t2\n", r"line 3: label 'x' is mapped twice \(first on line 2\)"),
    ("label\tcommon\nx\t1\ny\t1\n", r"line 3: labels 'x' and 'y' are both mapped to '1'"),
    ("label\tcommon\nx\t\n", r"line 2: empty label or common name"),
    ("label\tname\nx\t1\n", r"columns must be exactly label, common"),
])
def test_bad_label_maps_are_refused_in_one_line(tmp_path, text, message):
    p = tmp_path / "map.tsv"
    p.write_text(text)
    with pytest.raises(InputError, match=message) as e:
        read_subject_label_map(p)
    assert str(e.value).startswith(f"label map {p}") and "\n" not in str(e.value)


def test_label_map_against_the_subjects_markers(tmp_path):
    p = tmp_path / "map.tsv"
    p.write_text("label\tcommon\nlipL\t1\nH1\thead1\n")
    lm = read_subject_label_map(p, source="{sheet}/map.tsv")
    assert common_labels(["lipL", "2"], lm, known=["H1"]) == ["1", "2"]
    with pytest.raises(InputError, match=r"label map \{sheet\}/map.tsv, line 3: label 'H1' "
                                         "is not a marker of the subject"):
        common_labels(["lipL", "2"], lm)
    with pytest.raises(InputError, match=r"line 2: maps 'lipL' to '1', which the subject's "
                                         "own marker '1' is already called"):
        common_labels(["lipL", "1"], lm, known=["H1"])
    with pytest.raises(FileNotFoundError, match="label map .*absent.tsv: file not found"):
        read_subject_label_map(tmp_path / "absent.tsv")
    with pytest.raises(InputError, match=r"consensus: 0 subject\(s\)"):
        consensus_design([])
