"""The streamed loader against the whole-take loader (an independent path: every take held
whole, checked, aligned and filled at once), and its memory bound."""

import numpy as np
import pandas as pd
import pytest

from facemotion.errors import InputError
from facemotion.ingest import gap_windows
from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.gap_windows import FILL_RTOL
from facemotion.ingest.loading import load_dataset
from facemotion.ingest.streaming import Budget, stream_dataset
from facemotion.io.recording import Recording
from facemotion.io.trc import write_trc
from facemotion.ranking.qr import rank_from_gram

HEAD = ["H1", "H2", "H3", "H4"]
RATE = 60.0
MAX_GIB = 0.05
BLOCK = Budget.of(MAX_GIB, 44).frames  # frames per block of the streamed loader


def _take(seed: int, frames: int, gaps: bool) -> Recording:
    """40 face markers moved by 5 smooth sources, 4 head markers, rigid head motion, noise;
    with ``gaps``: short gaps, 1-s gaps, gaps at both ends, a far sample and a fast jump."""
    face = np.random.default_rng(0).normal(0.0, 35.0, (40, 3))  # one face, every take
    rng = np.random.default_rng(seed)
    head = np.array([[60.0, 0, 40], [-60, 0, 40], [0, 70, 60], [0, -20, 90]])
    t = np.arange(frames) / RATE
    src = np.sin(2 * np.pi * rng.uniform(0.3, 3, 5)[None] * t[:, None] + rng.uniform(0, 6, 5))
    fields = rng.normal(0, 2.0, (5, 40, 3))
    pts = np.concatenate([face[None] + np.tensordot(src, fields, 1),
                          np.broadcast_to(head, (frames, 4, 3))], axis=1)
    pts = pts + rng.normal(0, 0.05, pts.shape)
    ang = 0.02 * np.sin(2 * np.pi * 0.4 * t)
    c, s = np.cos(ang), np.sin(ang)
    R = np.zeros((frames, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    pts = np.einsum("fij,fnj->fni", R, pts) + 2.0 * np.sin(t)[:, None, None]
    if gaps:
        for _ in range(40):
            j, a = rng.integers(0, 40), rng.integers(1, frames - 10)
            pts[a:a + rng.integers(1, 5), j] = np.nan
        for j, a in ((3, 300), (11, 900), (12, 905)):
            pts[a:a + 60, j] = np.nan
        pts[:7, 20] = np.nan
        pts[-4:, 21] = np.nan
        pts[500, 30] += 400.0       # far from the face centre
        pts[700:705, 31] += 30.0    # a jump at 1,800 mm/s and back
        edge = 3000 // BLOCK * BLOCK
        pts[edge - 1:edge + 1, 15] = np.nan  # a short gap across two blocks
    labels = [f"M{j:02d}" for j in range(40)] + HEAD
    return Recording(labels, pts, RATE)


@pytest.fixture(scope="module")
def takes(tmp_path_factory):
    d = tmp_path_factory.mktemp("stream")
    paths = []
    for i, (frames, gaps) in enumerate(((4000, True), (700, False), (3100, True))):
        p = d / f"take{i}.trc"
        write_trc(p, _take(i, frames, gaps))
        paths.append(str(p))
    return d, paths


KW = dict(head_markers=HEAD, exclude_markers=HEAD, train=[0, 1], heldout=[2], units="mm")


def _both(d, paths, max_gib=MAX_GIB, **kw):
    whole = load_dataset(paths, "trc", **{**KW, **kw})
    streamed = stream_dataset(paths, "trc", d / "A.npz", **{**KW, **kw}, max_gib=max_gib)
    return whole, streamed, load_displacements(d / "A.npz")


def _same_dataset(whole, s, D) -> None:
    """The streamed dataset ``s`` (its file read back, ``D``) is the whole-take load's."""
    A = whole.displacements.A
    np.testing.assert_allclose(D.A, A, rtol=0, atol=FILL_RTOL * np.abs(A).max())
    for name in ("row_sentence", "row_frame", "fill_mask", "head_residual", "neutral"):
        np.testing.assert_array_equal(getattr(D, name), getattr(whole.displacements, name))
    pd.testing.assert_frame_equal(s.gap_report, whole.gap_report)
    pd.testing.assert_frame_equal(s.sentences, whole.sentences, check_exact=False, rtol=1e-12)


def test_streamed_dataset_equals_the_whole_take_load(takes):
    d, paths = takes
    assert BLOCK < 1000  # the takes are filled window by window
    whole, s, D = _both(d, paths)
    _same_dataset(whole, s, D)
    assert whole.gap_report["fill_method"].str.contains("pca").any()
    assert whole.gap_report["outlier_frames"].sum() == 2 * (1 + 5)
    # the Gram of the training rows, and the ranking made from it
    tr = whole.train.A
    G = tr.T @ tr
    assert s.train_rows == tr.shape[0]
    np.testing.assert_allclose(s.gram, G, rtol=0, atol=1e-12 * np.abs(G).max())
    r_whole = rank_from_gram(G, tr.shape[0], whole.displacements.labels)
    r_stream = rank_from_gram(s.gram, s.train_rows, s.labels)
    assert list(r_stream.order) == list(r_whole.order)
    np.testing.assert_allclose(r_stream.r, r_whole.r, rtol=1e-9)


def test_a_spline_window_too_narrow_is_caught_by_the_tolerance(takes, monkeypatch):
    """The comparison above can fail: with 2 knots either side of a short gap the window
    fill departs from the whole-take spline by far more than FILL_RTOL."""
    d, paths = takes
    monkeypatch.setattr(gap_windows, "SPLINE_KNOTS", 2)
    whole, _, D = _both(d, paths)
    A = whole.displacements.A
    assert np.abs(D.A - A).max() > 100 * FILL_RTOL * np.abs(A).max()


def test_a_window_beyond_the_memory_bound_is_an_error_naming_the_setting(takes):
    d, paths = takes
    with pytest.raises(InputError, match=r"take0\.trc: filling frames .* raise max_gib"):
        stream_dataset(paths, "trc", d / "B.npz", **KW, max_gib=0.02)
    assert not (d / "B.npz").exists()
    assert not [p for p in d.iterdir() if p.name.startswith(".B.npz")]


def _sentences(paths):
    """Sentences cut from the takes: take 0 in three (one boundary in the middle of the
    1,800 mm/s jump at frames 700-705, so each side judges its own part of it), take 1 in
    one, take 2 in two; frames between sentences left out."""
    b = 703 / RATE
    cuts = [(0, 1.0, b), (0, b, 30.0), (0, 30.5, 66.0), (1, 0.5, 10.0), (2, 0.0, 25.0),
            (2, 25.0, 51.0)]
    return [{"name": f"s{i + 1}", "take": paths[t], "start_s": a, "end_s": e}
            for i, (t, a, e) in enumerate(cuts)]


def test_sentences_cut_from_takes_stream_as_the_whole_take_path_cuts_them(takes, caplog):
    """Each take read once for all its sentences; each sentence checked, aligned, filled and
    streamed as the whole-take path does with the sentence it cuts: the same A, masks, gap
    report, sentences table, outlier warnings and Gram."""
    d, paths = takes
    kw = dict(sentences=_sentences(paths), train=[0, 1, 3, 4], heldout=[2, 5])
    with caplog.at_level("WARNING", logger="facemotion"):
        whole = load_dataset(paths, "trc", **{**KW, **kw})
        said_whole = [r.message for r in caplog.records]
        caplog.clear()
        s = stream_dataset(paths, "trc", d / "S.npz", **{**KW, **kw}, max_gib=MAX_GIB)
        said_stream = [r.message for r in caplog.records]
    assert said_stream == said_whole
    assert any("[s2]" in m and "'M31'" in m for m in said_whole)  # the jump's other side
    D = load_displacements(d / "S.npz")
    _same_dataset(whole, s, D)
    tr = whole.train.A
    np.testing.assert_allclose(s.gram, tr.T @ tr, rtol=0, atol=1e-12 * np.abs(tr.T @ tr).max())
    # in the dataset's order: s1, s2, s4, s5 (train), s3, s6
    assert list(whole.sentences["frames"]) == [643, 1097, 570, 1500, 2130, 1560]


def test_a_sentence_past_its_takes_end_is_the_whole_take_paths_error(takes):
    d, paths = takes
    cut = _sentences(paths)[:2] + [{"name": "late", "take": paths[1], "start_s": 5.0,
                                    "end_s": 99.0}]
    kw = {**KW, "train": [0, 1], "heldout": [2], "sentences": cut}
    with pytest.raises(InputError) as whole:
        load_dataset(paths, "trc", **kw)
    with pytest.raises(InputError) as streamed:
        stream_dataset(paths, "trc", d / "L.npz", **kw)
    assert str(streamed.value) == str(whole.value) and "late" in str(whole.value)
    assert not (d / "L.npz").exists()


def test_what_the_streamed_loader_does_not_take_is_an_error(takes):
    d, paths = takes
    with pytest.raises(InputError, match="max_gib: must be positive"):
        stream_dataset(paths, "trc", d / "C.npz", **KW, max_gib=0.0)


def test_the_checks_give_the_whole_take_errors(tmp_path):
    """A take with most samples far from the face: the same error by both loaders."""
    rec = _take(5, 400, False)
    rec.points[:, :30] *= 20.0
    p = tmp_path / "far.trc"
    write_trc(p, rec)
    kw = {**KW, "train": [0], "heldout": []}
    with pytest.raises(InputError) as whole:
        load_dataset([str(p)], "trc", **kw)
    with pytest.raises(InputError) as streamed:
        stream_dataset([str(p)], "trc", tmp_path / "A.npz", **kw, max_gib=MAX_GIB)
    assert str(streamed.value) == str(whole.value)


def test_a_scattered_load_gathers_the_single_jobs_gram_and_pivots(takes):
    """One job per take (head points, reference, take), then the sum: the single job's G to
    round-off, the same pivots; each take's part of A is the single job's rows."""
    from facemotion.ingest import scatter
    from facemotion.ingest.segments import Segment

    d, paths = takes
    roles = ["train", "train", "heldout"]
    parts = scatter.plan([Segment.from_param(p) for p in paths], roles)
    assert [p.sentences for p in parts] == [None] * 3 and [p.positions for p in parts] == [
        [0], [1], [2]]
    used = [f"M{j:02d}" for j in range(40)] + HEAD
    scans = [scatter.scan_heads(p.take, "trc", used, HEAD, units="mm") for p in parts]
    heads, _, rates = scatter.by_position(
        [scatter.heads_arrays(h, r, pr, p.positions) for (h, r, pr), p in zip(scans, parts,
                                                                              strict=True)], 0)
    ref = scatter.gather_reference(heads, rates, HEAD, paths[0])
    opts = dict(units="mm", head_markers=HEAD, exclude_markers=HEAD, max_gib=MAX_GIB)
    loaded = [scatter.load_take(p, "trc", d / f"part{i}.npz", head_reference=ref, **opts)
              for i, p in enumerate(parts)]
    G = scatter.gather_gram([s.gram for s in loaded], [s.train_rows for s in loaded])
    single = stream_dataset(paths, "trc", d / "single.npz", **KW, max_gib=MAX_GIB)
    np.testing.assert_allclose(G, single.gram, rtol=0, atol=1e-13 * np.abs(G).max())
    assert not np.array_equal(G, loaded[0].gram)  # the sum, not one take
    assert loaded[2].train_rows == 0 and not loaded[2].gram.any()  # held out: no Gram
    r_g = rank_from_gram(G, sum(s.train_rows for s in loaded), loaded[0].labels)
    r_s = rank_from_gram(single.gram, single.train_rows, single.labels)
    assert list(r_g.order) == list(r_s.order)
    A = load_displacements(d / "single.npz")
    for i in range(3):
        np.testing.assert_array_equal(load_displacements(d / f"part{i}.npz").A,
                                      A.A[A.row_sentence == i])
    with pytest.raises(InputError, match="no training sentence"):
        scatter.gather_gram([s.gram for s in loaded], [0, 0, 0])


def test_a_scattered_load_of_sentences_cut_from_takes(takes):
    """Takes cut into sentences, training and held-out sentences in the same take: one job per
    take reads it once for its sentences; gathered in the dataset's order, the head reference,
    the Gram and the held-out rows are the single job's."""
    from facemotion.ingest import scatter
    from facemotion.ingest.segments import Segment

    d, paths = takes
    sentences = [Segment.from_param(s) for s in _sentences(paths)]
    train, heldout = [0, 1, 3, 4], [2, 5]
    order = train + heldout
    roles = ["train"] * 4 + ["heldout"] * 2
    parts = scatter.plan([sentences[i] for i in order], roles)
    assert [p.positions for p in parts] == [[0, 1, 4], [2], [3, 5]]
    assert [p.roles for p in parts] == [["train", "train", "heldout"], ["train"],
                                        ["train", "heldout"]]
    used = [f"M{j:02d}" for j in range(40)] + HEAD
    files = [scatter.heads_arrays(*scatter.scan_heads(p.take, "trc", used, HEAD,
                                                      sentences=p.sentences, units="mm"),
                                  p.positions) for p in parts]
    heads, _, rates = scatter.by_position(files, 0)
    ref = scatter.gather_reference(heads, rates, HEAD, paths[0])
    kw = {**KW, "sentences": _sentences(paths), "train": train, "heldout": heldout}
    single = stream_dataset(paths, "trc", d / "single_cut.npz", **kw, max_gib=MAX_GIB)
    opts = dict(units="mm", head_markers=HEAD, exclude_markers=HEAD, max_gib=MAX_GIB)
    loaded = [scatter.load_take(p, "trc", d / f"cut{i}.npz", head_reference=ref, **opts)
              for i, p in enumerate(parts)]
    G = scatter.gather_gram([s.gram for s in loaded], [s.train_rows for s in loaded])
    np.testing.assert_allclose(G, single.gram, rtol=0, atol=1e-13 * np.abs(G).max())
    A = load_displacements(d / "single_cut.npz")
    blocks = scatter.heldout_blocks([(d / f"cut{i}.npz", p.heldout) for i, p in enumerate(parts)],
                                    block_rows=300)
    held = np.concatenate([b.copy() for b in blocks()])  # the blocks share one buffer
    # held-out sentences in the dataset's order (s3, s6) are the parts' (take 0's, take 2's)
    np.testing.assert_array_equal(held, A.A[A.row_sentence >= 4])


def test_one_take_without_head_markers_loads_in_one_pass(tmp_path, monkeypatch, caplog):
    """A take with nothing to fix goes to A and G while it is read; one with a gap after a
    few blocks is read again, in two passes. Either way A is the two-pass route's, digit for
    digit, G and the r values within round-off, the same pivots; and both are the whole-take
    load's. Nothing is left beside the output."""
    from facemotion.ingest import streaming

    kw = dict(train=[0], heldout=[], units="mm", neutral="mean_first_10")
    for name, gaps in (("clean", False), ("gapped", True)):
        rec = _take(3, 2500, False)
        if gaps:
            rec.points[2000:2003, 7] = np.nan
        p = tmp_path / f"{name}.trc"
        write_trc(p, rec)
        caplog.clear()
        with caplog.at_level("INFO", logger="facemotion"):
            s1 = stream_dataset([str(p)], "trc", tmp_path / f"{name}1.npz", **kw,
                                max_gib=0.004)
        said = caplog.text
        assert ("read again, in two passes" in said) == gaps
        assert "in one pass while it has nothing to fix" in said
        with monkeypatch.context() as m:
            m.setattr(streaming, "_one_pass", lambda *a, **k: None)
            s2 = stream_dataset([str(p)], "trc", tmp_path / f"{name}2.npz", **kw,
                                max_gib=0.004)
        whole = load_dataset([str(p)], "trc", **kw)
        A1 = load_displacements(tmp_path / f"{name}1.npz")
        A2 = load_displacements(tmp_path / f"{name}2.npz")
        for field in ("A", "fill_mask", "neutral", "row_frame", "head_residual"):
            np.testing.assert_array_equal(getattr(A1, field), getattr(A2, field))
        np.testing.assert_allclose(A1.A, whole.displacements.A, rtol=0,
                                   atol=FILL_RTOL * np.abs(A1.A).max())
        pd.testing.assert_frame_equal(s1.gap_report, s2.gap_report)
        pd.testing.assert_frame_equal(s1.sentences, s2.sentences)
        np.testing.assert_allclose(s1.gram, s2.gram, rtol=0, atol=1e-13 * np.abs(s2.gram).max())
        r1, r2 = (rank_from_gram(s.gram, s.train_rows, s.labels) for s in (s1, s2))
        assert list(r1.order) == list(r2.order)
        np.testing.assert_allclose(r1.r, r2.r, rtol=1e-9)
    assert sorted(x.name for x in tmp_path.iterdir()) == sorted(
        [f"{n}{i}.npz" for n in ("clean", "gapped") for i in (1, 2)] + ["clean.trc",
                                                                        "gapped.trc"])


def test_c3d_takes_stream_in_blocks_as_the_whole_take_load(tmp_path, monkeypatch):
    """C3D (Intel, float storage) through the block reader: the whole-take load's A to the
    fill tolerance, the same pivots; no take is read whole."""
    from facemotion.ingest import stream_scan
    from facemotion.io.c3d import write_c3d

    paths = []
    for i, (frames, gaps) in enumerate(((1500, True), (700, False))):
        p = tmp_path / f"take{i}.c3d"
        write_c3d(p, _take(10 + i, frames, gaps))
        paths.append(str(p))
    monkeypatch.setattr(stream_scan, "WholeTake", None)  # a whole read would fail here
    kw = {**KW, "train": [0], "heldout": [1]}
    whole = load_dataset(paths, "c3d", **kw)
    s = stream_dataset(paths, "c3d", tmp_path / "A.npz", **kw, max_gib=MAX_GIB)
    A, D = whole.displacements.A, load_displacements(tmp_path / "A.npz")
    np.testing.assert_allclose(D.A, A, rtol=0, atol=FILL_RTOL * np.abs(A).max())
    np.testing.assert_array_equal(D.fill_mask, whole.displacements.fill_mask)
    tr = whole.train.A
    r_whole = rank_from_gram(tr.T @ tr, tr.shape[0], whole.displacements.labels)
    r_stream = rank_from_gram(s.gram, s.train_rows, s.labels)
    assert list(r_stream.order) == list(r_whole.order)
    np.testing.assert_allclose(r_stream.r, r_whole.r, rtol=1e-9)
