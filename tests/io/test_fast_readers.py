"""The TRC/CSV fast path (C parser) against the exact line-by-line reader on the same files."""

from pathlib import Path

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.io import base, trc, wide_csv
from facemotion.io.recording import Recording
from facemotion.io.trc import read_trc, write_trc
from facemotion.io.wide_csv import read_csv, write_csv


def rec(F=500, n=17, seed=0):
    rng = np.random.default_rng(seed)
    P = rng.standard_normal((F, n, 3)) * 20.0
    P[10:40, 3] = np.nan
    P[:5, 0] = np.nan
    P[-3:, n - 1] = np.nan
    return Recording([f"M{j:02d}" for j in range(n)], P, 120.0)


def both(fn, path, **kw):
    """(fast, exact) readings, or the error message of each."""
    out = []
    for fast in (True, False):
        base.FAST_TEXT = fast
        try:
            out.append(fn(path, **kw))
        except InputError as e:
            out.append(str(e))
        finally:
            base.FAST_TEXT = True
    return out


def same(a, b):
    assert type(a) is type(b)
    if isinstance(a, str):
        assert a == b
    else:
        np.testing.assert_array_equal(a.points, b.points)
        assert (a.labels, a.rate, a.units, a.units_source) == (b.labels, b.rate, b.units,
                                                             b.units_source)


def variants(text: str, sep: str, first_data: int):
    lines = text.split("\n")
    yield "as written", text
    yield "crlf", text.replace("\n", "\r\n")
    yield "blank lines", "\n".join(lines[:first_data] + [""] + lines[first_data:first_data + 9]
                                   + ["", ""] + lines[first_data + 9:])
    if sep == "\t":
        yield "trailing tab", "\n".join(x + "\t" if i >= first_data and x else x
                                        for i, x in enumerate(lines))
    short = lines.copy()
    short[first_data + 7] = short[first_data + 7].rsplit(sep, 1)[0]
    yield "a field missing", "\n".join(short)
    long_ = lines.copy()
    long_[first_data + 3] += sep
    yield "one field too many", "\n".join(long_)
    extra = lines.copy()
    extra[first_data + 3] += sep + "7"
    yield "text beyond the fields", "\n".join(extra)
    word = lines.copy()
    word[first_data + 5] = word[first_data + 5].replace(sep, sep + "x" * 40, 1)
    yield "a word", "\n".join(word)
    nan = lines.copy()
    nan[first_data + 6] = nan[first_data + 6].replace(sep, sep + " nan ", 2)
    yield "nan text", "\n".join(nan)
    yield "cut", text[: len(text) - 37]
    spaces = lines.copy()
    spaces.insert(first_data + 2, "   ")
    yield "a line of spaces", "\n".join(spaces)
    yield "non-ascii", "\n".join(lines[:first_data + 1] + [lines[first_data + 1] + "\u00e9"]
                                  + lines[first_data + 2:])


@pytest.mark.parametrize("kind", ["trc", "csv"])
def test_fast_path_equals_the_exact_reader(tmp_path, kind):
    r = rec()
    path = tmp_path / f"a.{kind}"
    (write_trc if kind == "trc" else write_csv)(path, r)
    fn = read_trc if kind == "trc" else read_csv
    text = path.read_text()
    first = 6 if kind == "trc" else 1
    sep = "\t" if kind == "trc" else ","
    taken = 0
    for name, variant in variants(text, sep, first):
        p = tmp_path / f"v.{kind}"
        p.write_text(variant, encoding="utf-8")
        fast, exact = both(fn, p)
        same(fast, exact)
        if kind == "trc":
            taken += trc._read_trc_fast(Path(p), None) is not None
        else:
            taken += wide_csv._read_csv_fast(Path(p)) is not None
        if name == "as written":
            np.testing.assert_allclose(fast.points, r.points, atol=5e-7)
        if name in ("a field missing", "a word", "cut"):
            assert isinstance(fast, str), name  # an error, the exact reader's
    assert taken >= 3  # regular variants went through the C parser


def test_trc_units_and_header_errors_match(tmp_path):
    r = rec(F=50, n=4)
    write_trc(tmp_path / "a.trc", r)
    text = (tmp_path / "a.trc").read_text()
    (tmp_path / "cm.trc").write_text(text.replace("\tmm\t", "\tcm\t", 1))
    fast, exact = both(read_trc, tmp_path / "cm.trc")
    same(fast, exact)
    np.testing.assert_allclose(fast.points, 10 * r.points, atol=5e-6, equal_nan=True)
    (tmp_path / "frames.trc").write_text(text.replace("\t50\t4\t", "\t51\t4\t", 1))
    fast, exact = both(read_trc, tmp_path / "frames.trc")
    assert isinstance(fast, str) and fast == exact and "NumFrames=51" in fast
