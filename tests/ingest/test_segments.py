"""Segmentation of long takes: the [start, end) rule, the three sources, their errors, and a take
cut into sentences giving the same A as the sentences in separate files."""

from __future__ import annotations

import math

import ezc3d
import numpy as np
import pytest
from praatio import textgrid
from praatio.utilities.constants import Interval, Point

from facemotion.errors import InputError
from facemotion.ingest.loading import load_dataset
from facemotion.ingest.segments import (
    Segment,
    cut,
    first_sample_at_or_after,
    frame_range,
    pair_events,
    parse_spec,
    read_c3d_events,
    segment_subject,
)
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording
from facemotion.study.sheet import read_subject_sheet, resolve_datasets

RATE = 60.0


# ----------------------------------------------------------------------------- the rule

@pytest.mark.parametrize("rate", [60.0, 59.94, 69.9000015258789, 25.0, 100.0])
def test_first_sample_matches_brute_force(rate):
    rng = np.random.default_rng(1)
    times = np.arange(4000) / rate  # the sample times, as i / rate
    # random times, and times exactly on samples (the boundary case of [start, end))
    for t in list(rng.uniform(0, 30, 300)) + [float(x) for x in times[::37]]:
        expected = int(np.flatnonzero(times >= t)[0])
        assert first_sample_at_or_after(t, rate) == expected


def test_frame_range_is_start_inclusive_end_exclusive():
    n = 120
    times = np.arange(n) / RATE
    for start, end in [(10 / RATE, 20 / RATE), (0.1, 0.5), (0.0, n / RATE), (1.2345, 1.9)]:
        i0, i1 = frame_range(start, end, RATE, n, "take")
        inside = np.flatnonzero((times >= start) & (times < end))
        assert (i0, i1) == (inside[0], inside[-1] + 1)


def test_frame_range_errors():
    with pytest.raises(InputError, match="ends beyond the take .120 frames at 60 Hz = 2 s"):
        frame_range(1.0, 2.0001, RATE, 120, "take.c3d")
    with pytest.raises(InputError, match="holds no sample"):
        frame_range(0.101, 0.105, RATE, 120, "take.c3d")


def _planted_take(n_sentences=4, seed=0, pad=7):
    """Sentences of random lengths, with `pad` frames of other motion between them."""
    rng = np.random.default_rng(seed)
    labels = ["a", "b", "c"]
    parts, bounds, start = [], [], 0
    sentences = []
    for _ in range(n_sentences):
        gap = rng.normal(size=(pad, 3, 3)) * 100
        parts.append(gap)
        start += pad
        length = int(rng.integers(20, 40))
        s = rng.normal(size=(length, 3, 3))
        sentences.append(s)
        parts.append(s)
        bounds.append((start, start + length))
        start += length
    return Recording(labels, np.concatenate(parts), RATE, source="take"), sentences, bounds


def test_cut_returns_exactly_the_planted_sentences():
    rec, sentences, bounds = _planted_take()
    for s, (a, b) in zip(sentences, bounds, strict=True):
        part = cut(rec, Segment("x", "take", a / RATE, b / RATE))
        assert np.array_equal(part.points, s)


# ----------------------------------------------------------------------------- parsing

@pytest.mark.parametrize("cell, match", [
    ("praat:x.TextGrid#s", "must start with textgrid:, events: or tsv:"),
    ("textgrid:x.TextGrid", "textgrid:<path>#<tier name>"),
    ("textgrid:#tier", "textgrid:<path>#<tier name>"),
    ("events:Start", "events:<start label>,<end label>"),
    ("events:a,b,c", "events:<start label>,<end label>"),
    ("tsv:", "tsv:<path>"),
])
def test_bad_spec(cell, match):
    with pytest.raises(InputError, match=match):
        parse_spec(cell, "sheet row 2")


def test_spec_kinds():
    assert parse_spec("textgrid:tg/{stem}.TextGrid#sentences", "w").tier == "sentences"
    spec = parse_spec("events: Sentence Start , Sentence End", "w")
    assert (spec.start_label, spec.end_label) == ("Sentence Start", "Sentence End")
    assert parse_spec("tsv:intervals.tsv", "w").path == "intervals.tsv"


# ----------------------------------------------------------------------------- TextGrid

def _textgrid(path, tiers: dict, xmax=10.0):
    tg = textgrid.Textgrid()
    for name, entries in tiers.items():
        if entries and isinstance(entries[0], Point):
            tg.addTier(textgrid.PointTier(name, entries, 0, xmax))
        else:
            tg.addTier(textgrid.IntervalTier(name, entries, 0, xmax))
    tg.save(str(path), format="long_textgrid", includeBlankSpaces=True)


def test_textgrid_tier_gives_named_sentences(tmp_path):
    take = tmp_path / "block1.c3d"
    take.write_bytes(b"")
    _textgrid(tmp_path / "block1.TextGrid", {
        "words": [Interval(0.5, 0.9, "the")],
        "sentences": [Interval(0.5, 2.0, "the  dog\tbarked"), Interval(2.0, 2.5, " "),
                      Interval(3.0, 4.25, "a cat sat")],
    })
    segs, sources = segment_subject("textgrid:{stem}.TextGrid#sentences", [str(take)], "c3d",
                                    tmp_path, "row 2")
    assert [(s.name, s.start_s, s.end_s) for s in segs] == [
        ("the dog barked", 0.5, 2.0), ("a cat sat", 3.0, 4.25)]
    assert sources == [str(tmp_path / "block1.TextGrid")]


def test_textgrid_errors(tmp_path):
    take = str(tmp_path / "b1.c3d")
    _textgrid(tmp_path / "b1.TextGrid", {
        "sentences": [Interval(0.5, 2.0, "one")], "blank": [Interval(0.5, 2.0, "")],
        "marks": [Point(1.0, "x")]})
    seg = "textgrid:{stem}.TextGrid#"
    with pytest.raises(InputError, match=r"row 2.*b1.TextGrid: no tier 'sentence' "
                                         r"\(tiers: 'sentences', 'blank', 'marks'\)"):
        segment_subject(seg + "sentence", [take], "c3d", tmp_path, "row 2")
    with pytest.raises(InputError, match="tier 'blank' has no non-empty interval"):
        segment_subject(seg + "blank", [take], "c3d", tmp_path, "row 2")
    with pytest.raises(InputError, match="tier 'marks' is a point tier"):
        segment_subject(seg + "marks", [take], "c3d", tmp_path, "row 2")
    with pytest.raises(InputError, match="other.TextGrid: TextGrid file not found"):
        segment_subject("textgrid:other.TextGrid#s", [take], "c3d", tmp_path, "row 2")
    with pytest.raises(InputError, match=r"must hold \{stem\}"):
        segment_subject("textgrid:b1.TextGrid#sentences", [take, take + "2"], "c3d", tmp_path,
                        "row 2")
    (tmp_path / "bad.TextGrid").write_text("File type = \"ooTextFile\"\nnonsense\n")
    with pytest.raises(InputError, match="bad.TextGrid: cannot read as a Praat TextGrid"):
        segment_subject("textgrid:bad.TextGrid#s", [take], "c3d", tmp_path, "row 2")


def test_one_textgrid_cuts_one_take(tmp_path):
    """day1/block1.c3d and day2/block1.c3d with '{stem}.TextGrid' beside the sheet: one file
    for two takes is refused, naming both."""
    takes = []
    for day in ("day1", "day2"):
        (tmp_path / day).mkdir()
        takes.append(str(tmp_path / day / "block1.c3d"))
    _textgrid(tmp_path / "block1.TextGrid", {"sentence": [Interval(0.5, 2.0, "one")]})
    with pytest.raises(InputError, match=r"takes .*day1/block1.c3d and .*day2/block1.c3d "
                                         r"both resolve to the TextGrid .*block1.TextGrid"):
        segment_subject("textgrid:{stem}.TextGrid#sentence", takes, "c3d", tmp_path, "row 2")
    segs, _ = segment_subject("textgrid:{stem}.TextGrid#sentence", takes[:1], "c3d",
                              tmp_path, "row 2")
    assert [s.name for s in segs] == ["one"]


def test_textgrid_saved_by_praat_in_utf16(tmp_path):
    """Praat saves non-ASCII TextGrids as UTF-16; the sentence names keep their letters."""
    _textgrid(tmp_path / "t.TextGrid", {"s": [Interval(0.25, 1.5, "Ça va, señor?")]})
    text = (tmp_path / "t.TextGrid").read_text(encoding="utf-8")
    (tmp_path / "t.TextGrid").write_text(text, encoding="utf-16")
    segs, _ = segment_subject("textgrid:t.TextGrid#s", [str(tmp_path / "t.c3d")], "c3d",
                              tmp_path, "row 2")
    assert segs[0].name == "Ça va, señor?"


# ----------------------------------------------------------------------------- TSV

def _tsv(path, rows):
    path.write_text("take\tstart_s\tend_s\tname\n"
                    + "".join("\t".join(map(str, r)) + "\n" for r in rows))


def test_tsv_orders_by_time_and_makes_names_unique(tmp_path):
    takes = [str(tmp_path / "blockA.trc"), str(tmp_path / "blockB.trc")]
    _tsv(tmp_path / "iv.tsv", [("blockB", 1.0, 2.0, "hello"), ("blockA", 3, 4, "second"),
                               ("blockA.trc", 0.5, 1.5, "hello")])
    segs, _ = segment_subject("tsv:iv.tsv", takes, "trc", tmp_path, "row 3")
    assert [(s.name, s.take, s.start_s) for s in segs] == [
        ("hello", takes[0], 0.5), ("second", takes[0], 3.0), ("hello [2]", takes[1], 1.0)]


@pytest.mark.parametrize("rows, match", [
    ([("blockA", 0, 1, "a"), ("blockC", 0, 1, "c")],
     r"iv.tsv, line 3: take 'blockC' is not a recording of this subject .*blockA, blockB"),
    ([("blockA", 0, 1.5, "a"), ("blockA", 1.2, 2, "b"), ("blockB", 0, 1, "c")],
     r"intervals 0-1.5 s and 1.2-2 s overlap"),
    ([("blockA", 0, 1, "a")], "have no row for take 'blockB'"),
    ([("blockA", 2, 1, "a"), ("blockB", 0, 1, "c")], "empty or runs backwards"),
    ([("blockA", -0.1, 1, "a"), ("blockB", 0, 1, "c")], "starts before the take"),
    ([("blockA", "x", 1, "a")], r"line 2: start_s 'x' is not a number"),
    ([("blockA", 0, 1, " ")], "line 2: empty name"),
])
def test_tsv_errors(tmp_path, rows, match):
    takes = [str(tmp_path / "blockA.trc"), str(tmp_path / "blockB.trc")]
    _tsv(tmp_path / "iv.tsv", rows)
    with pytest.raises(InputError, match=match):
        segment_subject("tsv:iv.tsv", takes, "trc", tmp_path, "row 3")


def test_tsv_hash_inside_a_name_is_kept(tmp_path):
    """Only whole lines starting with '#' are comments; their lines still count."""
    (tmp_path / "iv.tsv").write_text("# intervals of block A\ntake\tstart_s\tend_s\tname\n"
                                     "A\t0\t1\tsentence #1\n#A\t1\t2\tleft out\n"
                                     "A\t2\t3\tsentence #2 # two\nA\tx\t4\tbad\n")
    with pytest.raises(InputError, match=r"iv.tsv, line 6: start_s 'x' is not a number"):
        segment_subject("tsv:iv.tsv", [str(tmp_path / "A.c3d")], "c3d", tmp_path, "row 2")
    text = (tmp_path / "iv.tsv").read_text().rsplit("A\tx", 1)[0]
    (tmp_path / "iv.tsv").write_text(text)
    segs, _ = segment_subject("tsv:iv.tsv", [str(tmp_path / "A.c3d")], "c3d", tmp_path,
                              "row 2")
    assert [s.name for s in segs] == ["sentence #1", "sentence #2 # two"]


def test_tsv_missing_columns(tmp_path):
    (tmp_path / "iv.tsv").write_text("take\tstart\tend\tname\nA\t0\t1\tx\n")
    with pytest.raises(InputError, match="missing column.s. start_s, end_s"):
        segment_subject("tsv:iv.tsv", [str(tmp_path / "A.c3d")], "c3d", tmp_path, "row 2")


# ----------------------------------------------------------------------------- C3D events

def _c3d_with_events(path, rec: Recording, events, first_frame=0):
    """Write ``rec`` with EVENT entries [(label, seconds[, subject])] (times from frame 1)."""
    write_c3d(path, rec)
    c = ezc3d.c3d(str(path))
    c["header"]["points"]["first_frame"] = first_frame
    for ev in events:
        label, t = ev[0], ev[1]
        c.add_event(time=[int(t // 60), t - 60 * (t // 60)], context="General", label=label,
                    subject=ev[2] if len(ev) > 2 else "")
    c.write(str(path))


def test_event_pairs_cut_on_the_event_frames(tmp_path):
    rec, sentences, bounds = _planted_take()
    take = tmp_path / "block.c3d"
    _c3d_with_events(take, rec, [(lab, f / RATE) for a, b in bounds
                                 for lab, f in (("Start", a), ("End", b))] + [("Foot", 0.1)])
    ev = read_c3d_events(take)
    pairs = pair_events(ev.events, "Start", "End", str(take))
    # float32 event times were snapped back onto the sample times
    assert pairs == [(a / RATE, b / RATE) for a, b in bounds]
    segs, _ = segment_subject("events:Start,End", [str(take)], "c3d", tmp_path, "row 2")
    assert [s.name for s in segs] == [f"block_{k:02d}" for k in range(1, 5)]
    full = read_c3d(take)
    for seg, s in zip(segs, sentences, strict=True):
        assert np.array_equal(cut(full, seg).points, s.astype(np.float32).astype(float))


def test_event_times_count_from_the_first_captured_frame(tmp_path):
    """A trial whose first frame is 51: an event at capture time 1.5 s is file time 0.5 s."""
    rec, _, _ = _planted_take()
    take = tmp_path / "cropped.c3d"
    _c3d_with_events(take, rec, [("Start", 1.5), ("End", 2.0)], first_frame=60)
    ev = read_c3d_events(take)
    assert ev.events == [("Start", 0.5), ("End", 1.0)]


def test_events_of_another_subject_are_ignored(tmp_path):
    rec, _, _ = _planted_take()
    take = tmp_path / "two.c3d"
    _c3d_with_events(take, rec, [("Start", 0.5, "Ann"), ("End", 1.0, "Ann"),
                                 ("Start", 0.7, "Bob"), ("End", 1.2, "Bob")])
    assert read_c3d_events(take, "Bob").events == [("Start", 0.7), ("End", 1.2)]
    with pytest.raises(InputError, match="unpaired events"):
        pair_events(read_c3d_events(take).events, "Start", "End", "two.c3d")


@pytest.mark.parametrize("events, match", [
    ([("Start", 0.5), ("Start", 0.8), ("End", 1.0)],
     r"unpaired events: 'Start' at 0.5000 s is followed by another 'Start' at 0.8000 s"),
    ([("End", 0.2), ("Start", 0.5), ("End", 1.0)], r"'End' at 0.2000 s has no 'Start' before"),
    ([("Start", 0.5), ("End", 1.0), ("Start", 1.5)], r"'Start' at 1.5000 s has no 'End' after"),
    ([("Foot Strike", 0.5)], r"no events labelled 'Start' or 'End' .events in the file: "
                             r"'Foot Strike'\)"),
])
def test_event_errors(events, match):
    with pytest.raises(InputError, match=match):
        pair_events(events, "Start", "End", "take.c3d")


def test_event_interval_beyond_the_take_and_no_events(tmp_path):
    rec, _, _ = _planted_take()  # 4 sentences + padding, < 3 s at 60 Hz
    take = tmp_path / "long.c3d"
    _c3d_with_events(take, rec, [("Start", 0.5), ("End", 9.0)])
    with pytest.raises(InputError, match=r"row 2.*long.c3d: event 2 'End' at 9 s is outside "
                                         r"the take \(0-"):
        segment_subject("events:Start,End", [str(take)], "c3d", tmp_path, "row 2")
    plain = tmp_path / "plain.c3d"
    write_c3d(plain, rec)
    with pytest.raises(InputError, match="plain.c3d: no events"):
        segment_subject("events:Start,End", [str(plain)], "c3d", tmp_path, "row 2")
    with pytest.raises(InputError, match="reads C3D events, but the format is 'trc'"):
        segment_subject("events:Start,End", [str(plain)], "trc", tmp_path, "row 2")


# ----------------------------------------------------------------------------- end to end

def _sentence_recordings(n=5, seed=3):
    """Sentences of a talker: common head markers H1-H3 with a shared head motion, face
    markers moving by a few mm; first frames differ (each sentence has its own neutral)."""
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(8, 3)) * 40
    recs = []
    for _ in range(n):
        F = int(rng.integers(25, 45))
        t = np.arange(F) / RATE
        pts = base + rng.normal(size=(1, 8, 3)) * 0.1
        pts = pts + np.sin(2 * np.pi * rng.uniform(1, 4) * t)[:, None, None] * \
            rng.normal(size=(1, 8, 3)) * 2
        pts[:, :3] = base[:3] + rng.normal(size=(F, 1, 3)) * 0.5  # rigid translation of head
        pts[rng.integers(0, F), 5] = np.nan  # one missing sample, filled by the loader
        recs.append(Recording([f"H{j}" for j in (1, 2, 3)] + [f"m{j}" for j in range(5)],
                              pts, RATE))
    return recs


def test_take_cut_by_textgrid_gives_the_same_A_as_one_file_per_sentence(tmp_path):
    recs = _sentence_recordings()
    split_dir = tmp_path / "split"
    split_dir.mkdir()
    names = [f"sent{k + 1:02d}" for k in range(len(recs))]
    for name, r in zip(names, recs, strict=True):
        write_c3d(split_dir / f"{name}.c3d", r)
    # two blocks: sentences 1-3 and 4-5, with 5 frames of silence before each sentence
    take_dir = tmp_path / "takes"
    take_dir.mkdir()
    blocks = {"block1": [0, 1, 2], "block2": [3, 4]}
    for block, members in blocks.items():
        parts, entries, f = [], [], 0
        for k in members:
            parts.append(np.full((5, 8, 3), 7.0))
            f += 5
            parts.append(recs[k].points)
            entries.append(Interval(f / RATE, (f + recs[k].n_frames) / RATE, names[k]))
            f += recs[k].n_frames
        write_c3d(take_dir / f"{block}.c3d", Recording(recs[0].labels, np.concatenate(parts),
                                                        RATE))
        _textgrid(take_dir / f"{block}.TextGrid", {"sentence": entries}, xmax=f / RATE)
    sheet = tmp_path / "subjects.tsv"
    sheet.write_text(
        "subject\trecordings\tformat\thead_markers\texclude_markers\tsegments\n"
        "split\tsplit/sent*.c3d\tc3d\tH1,H2,H3\tH1,H2,H3\t\n"
        "blocks\ttakes/block*.c3d\tc3d\tH1,H2,H3\tH1,H2,H3\t"
        "textgrid:takes/{stem}.TextGrid#sentence\n")
    subjects = read_subject_sheet(sheet)
    assert subjects["blocks"].sentence_names == names
    datasets = resolve_datasets(subjects, {"b": {"subject": "blocks", "train": "1,3-4",
                                                 "heldout": "5"}},
                                default_per_subject=True)
    assert (datasets["blocks"].train, datasets["blocks"].heldout) == ([0, 1, 2, 3], [4])
    loaded = {}
    for sid in ("split", "blocks"):
        s, d = subjects[sid], datasets[sid]
        loaded[sid] = load_dataset(
            s.recordings, s.format, head_markers=s.head_markers,
            exclude_markers=s.exclude_markers, train=d.train, heldout=d.heldout,
            sentences=[x.to_param() for x in s.sentences])
    a, b = loaded["split"].displacements, loaded["blocks"].displacements
    assert np.array_equal(a.A, b.A)  # bit-identical
    assert a.sentences == b.sentences == names
    assert np.array_equal(a.fill_mask, b.fill_mask)
    assert list(loaded["blocks"].sentences["frames"]) == [r.n_frames for r in recs]
    assert math.isclose(loaded["blocks"].sentences["start_s"][3], 5 / RATE)
