"""copy_markers in a streamed load (facemotion.ingest.copy_windows): each take's offset equals
the whole-take copy's (facemotion.ingest.copy_fill), including a take where the target is never
measured, whose offset (the median over every take) cancels in its displacements and so is
checked here directly."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.copy_fill import copy_fill
from facemotion.ingest.copy_windows import CopyPlan, median_of_differences, pair_differences
from facemotion.ingest.loading import remove_head_motion
from facemotion.ingest.stream_scan import scan_take
from facemotion.ingest.streaming import head_reference
from facemotion.ingest.validation import Limits
from facemotion.io.registry import read_recording

HEAD = [f"H{i}" for i in range(1, 7)]


def _takes(tmp_path, lose_all_in):
    from facemotion.io.c3d import write_c3d
    from facemotion.virtual.talker import simulate_subject

    subj = simulate_subject("S1", seed=4, n_sentences=3, sentence_duration=(0.6, 0.8))
    paths = []
    for i, rec in enumerate(subj.recordings):
        if i in lose_all_in:
            rec.points[:, rec.labels.index("13")] = np.nan
        paths.append(str(tmp_path / f"t{i}.c3d"))
        write_c3d(paths[-1], rec)
    labels = subj.recordings[0].labels
    keep = [m for m in labels if m not in HEAD]
    return paths, keep, keep + HEAD


def _scans(tmp_path, paths, used):
    scans = [scan_take(p, "c3d", used, Limits(), tmp_path / f"s{i}.f8", head_markers=HEAD)
             for i, p in enumerate(paths)]
    reference, _ = head_reference(scans, HEAD, "S1")
    return scans, reference


def _whole_offsets(paths, keep):
    """Each take's 13 - 11 after the whole-take copy, where 13 was copied."""
    recs = [read_recording(p, "c3d") for p in paths]
    recs, _ = remove_head_motion(recs, HEAD, "S1")
    recs = [r.select(keep) for r in recs]
    out, _ = copy_fill(recs, [("13", "11")])
    j13, j11 = keep.index("13"), keep.index("11")
    return [(r.points[:, j13] - r.points[:, j11])[r.filled[:, j13]] for r in out]


def test_offsets_equal_the_whole_take_copys(tmp_path):
    paths, keep, used = _takes(tmp_path, lose_all_in=(1,))
    scans, reference = _scans(tmp_path, paths, used)
    plan = CopyPlan.of(scans, [("13", "11")], keep, head_markers=HEAD, reference=reference,
                       block_frames=7, where="S1")
    whole = _whole_offsets(paths, keep)
    for k in range(3):
        assert len(whole[k]) > 0
        np.testing.assert_allclose(whole[k], np.broadcast_to(plan.offsets[k][0], whole[k].shape),
                                   rtol=0, atol=1e-9)
    # the never-measured take's offset is the pooled median, not a first frame's
    pooled = np.concatenate([d[0] for d in (
        pair_differences(s, [("13", "11")], HEAD, reference, 5) for s in scans)])
    np.testing.assert_allclose(plan.offsets[1][0], np.median(pooled, axis=0), rtol=0, atol=1e-12)
    assert np.abs(plan.offsets[1][0] - plan.offsets[0][0]).max() > 1e-6
    # a scattered part given the dataset's medians uses them
    given = np.array([[1.0, 2.0, 3.0]])
    part = CopyPlan.of(scans, [("13", "11")], keep, head_markers=HEAD, reference=reference,
                       block_frames=7, where="S1", pooled=given)
    np.testing.assert_array_equal(part.offsets[1][0], given[0])
    with pytest.raises(InputError, match="never measured in the same frame"):
        CopyPlan.of(scans, [("13", "11")], keep, head_markers=HEAD, reference=reference,
                    block_frames=7, where="S1", pooled=np.full((1, 3), np.nan))
    np.testing.assert_array_equal(part.offsets[0][0], plan.offsets[0][0])


def test_left_missing_keeps_a_target_whose_source_is_missing_too():
    plan = CopyPlan([("b", "a")], [(1, 0)], [(1, 0)], [[np.zeros(3)]])
    miss = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], dtype=bool)
    np.testing.assert_array_equal(plan.left_missing(miss),
                                  [[0, 0], [1, 1], [1, 0], [0, 0]])
    pts = np.arange(24, dtype=float).reshape(4, 2, 3)
    pts[miss] = np.nan
    plan.copy(0, pts)
    assert np.isnan(pts[1]).all() and np.array_equal(pts[0, 1], pts[0, 0])


def test_no_take_with_both_measured_is_an_error(tmp_path):
    paths, keep, used = _takes(tmp_path, lose_all_in=(0, 1, 2))
    scans, reference = _scans(tmp_path, paths, used)
    assert median_of_differences([pair_differences(s, [("13", "11")], HEAD, reference, 9)
                                  for s in scans]) == [None]
    with pytest.raises(InputError, match=r"^S1: markers '13' and '11' are never measured"):
        CopyPlan.of(scans, [("13", "11")], keep, head_markers=HEAD, reference=reference,
                    block_frames=7, where="S1")


def test_a_scattered_load_gathers_the_single_jobs_median_and_rows(tmp_path):
    """Each take's job keeps the pair's and head columns (scan_heads), the gather step takes
    the median over every take: the single job's offset for the take that never measured 13;
    each take's part of A is the single streamed job's rows."""
    from facemotion.ingest import scatter
    from facemotion.ingest.displacement_file import load_displacements
    from facemotion.ingest.streaming import stream_dataset

    paths, keep, used = _takes(tmp_path, lose_all_in=(1,))
    pairs = [("13", "11")]
    scanned = [scatter.scan_heads(p, "c3d", used, HEAD, copy_markers=pairs) for p in paths]
    heads, points, rates = scatter.by_position(
        [scatter.heads_arrays(h, r, pp, [i]) for i, (h, r, pp) in enumerate(scanned)], 1)
    ref = scatter.gather_reference(heads, rates, HEAD, "S1")
    medians = scatter.gather_copy_medians(points, pairs, rates[0], HEAD, ref)
    assert medians.shape == (1, 3)
    scans, reference = _scans(tmp_path, paths, used)
    np.testing.assert_array_equal(ref, reference)
    plan = CopyPlan.of(scans, pairs, keep, head_markers=HEAD, reference=reference,
                       block_frames=7, where="S1")
    np.testing.assert_allclose(medians[0], plan.offsets[1][0], rtol=0, atol=1e-12)
    opts = dict(head_markers=HEAD, exclude_markers=HEAD, copy_markers=pairs)
    single = stream_dataset(paths, "c3d", tmp_path / "single.npz", train=[0, 1, 2], heldout=[],
                            **opts)
    A = load_displacements(tmp_path / "single.npz").A
    start = 0
    for i, p in enumerate(paths):
        part = scatter.load_take(scatter.TakePart(p, None, ["train"], [i]), "c3d",
                                 tmp_path / f"part{i}.npz", head_reference=ref,
                                 copy_medians=medians, **opts)
        rows = load_displacements(tmp_path / f"part{i}.npz").A
        np.testing.assert_array_equal(rows, A[start:start + len(rows)])
        start += len(rows)
        assert part.gap_report.set_index("marker").loc["13", "fill_method"] == "copy:11"
    assert start == len(A) and single.train_rows == len(A)
