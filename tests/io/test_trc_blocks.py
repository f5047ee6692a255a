"""The TRC block reader against the whole-file reader: the same numbers, the same errors,
wherever the blocks cut the file."""

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.io import base, trc_blocks
from facemotion.io.recording import Recording
from facemotion.io.trc import read_trc, write_trc
from facemotion.io.trc_blocks import open_trc_blocks


def _file(tmp_path, frames=300, name="a.trc"):
    rng = np.random.default_rng(1)
    pts = rng.normal(0, 40, (frames, 6, 3))
    pts[50:60, 2] = np.nan
    p = tmp_path / name
    write_trc(p, Recording([f"M{j}" for j in range(6)], pts, 120.0))
    return p


def _read_blocks(p, block_bytes):
    tb = open_trc_blocks(p)
    got = list(tb.blocks(block_bytes))
    starts = [a for a, _ in got]
    pts = np.concatenate([b for _, b in got])
    assert starts == list(np.cumsum([0] + [len(b) for _, b in got[:-1]]))
    return tb, pts, len(got)


@pytest.fixture(params=["arrow", "loadtxt", "pandas"])
def parser(request, monkeypatch):
    """Each parser of plain blocks: pyarrow's (narrow lines), numpy's loadtxt (wide) and
    pandas' (the blocks these refuse)."""
    if request.param == "loadtxt":
        monkeypatch.setattr(trc_blocks, "WIDE_COLUMNS", 0)
    if request.param == "pandas":
        monkeypatch.setattr(trc_blocks, "_arrow", lambda c, n: None)
    return request.param


@pytest.mark.parametrize("block_bytes", [200, 997, 4096, 10**7])
def test_blocks_give_the_whole_file_reading(tmp_path, block_bytes, parser):
    p = _file(tmp_path)
    rec = read_trc(p)
    tb, pts, n = _read_blocks(p, block_bytes)
    assert (n > 1) == (block_bytes < 10**7)
    np.testing.assert_array_equal(pts, rec.points)
    assert (tb.labels, tb.rate, tb.units) == (rec.labels, rec.rate, rec.units)


def _lines(p):
    return p.read_text().splitlines(keepends=True)


def _edit(p, line_no, fn):
    lines = _lines(p)
    lines[line_no - 1] = fn(lines[line_no - 1])
    p.write_text("".join(lines))


CASES = {
    # (line to edit, edit): the whole-file reader's error is the block reader's
    "short line": (200, lambda s: s.rsplit("\t", 2)[0] + "\n"),
    "text beyond": (150, lambda s: s.rstrip("\n") + "\tx\n"),
    "non-numeric": (120, lambda s: s.replace("\t", "\tabc", 1).replace("abc", "", 0)),
    "frame repeated": (250, lambda s: "243" + s[s.index("\t"):]),
    "time off grid": (280, lambda s: s.split("\t")[0] + "\t9.5\t"
                      + "\t".join(s.split("\t")[2:])),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("block_bytes", [300, 10**7])
def test_the_strict_checks_run_in_block_mode(tmp_path, case, block_bytes, parser):
    p = _file(tmp_path)
    line, fn = CASES[case]
    _edit(p, line, fn)
    with pytest.raises(InputError) as whole:
        read_trc(p)
    with pytest.raises(InputError) as blocks:
        _read_blocks(p, block_bytes)
    assert str(blocks.value) == str(whole.value)
    assert f"line {line}" in str(blocks.value)


def test_a_slow_drift_of_time_is_caught_across_blocks(tmp_path):
    """Each step a little long: within a quarter frame of its neighbour everywhere, off the
    1/DataRate grid of the first time after a while (the block must carry t0)."""
    p = _file(tmp_path)
    lines = _lines(p)
    for i in range(6, len(lines)):
        f = lines[i].split("\t")
        f[1] = f"{(i - 6) * (1.01 / 120.0):.6f}"
        lines[i] = "\t".join(f)
    p.write_text("".join(lines))
    with pytest.raises(InputError) as whole:
        read_trc(p)
    with pytest.raises(InputError, match=r"line 32: Time .* off the 1/DataRate grid") as blocks:
        _read_blocks(p, 300)  # about 8 lines a block
    assert str(blocks.value) == str(whole.value)


def test_counts_and_the_last_line_end(tmp_path):
    p = _file(tmp_path)
    text = p.read_text()
    p.write_text(text + text.splitlines(keepends=True)[-1])
    with pytest.raises(InputError, match="NumFrames=300 but there are more data lines"):
        _read_blocks(p, 500)
    p.write_text("".join(text.splitlines(keepends=True)[:-1]))
    with pytest.raises(InputError, match="NumFrames=300 but there are 299 data lines"):
        _read_blocks(p, 500)
    p.write_text(text.rstrip("\n"))
    with pytest.raises(InputError, match="the last one, has no line end"):
        _read_blocks(p, 500)


@pytest.mark.parametrize("fmt", ["%.6f", "%.17g"])
def test_plain_blocks_parse_as_python_floats(tmp_path, monkeypatch, parser, fmt):
    """Blocks without gaps go through the fast parser (counted) and give the numbers of the
    exact line-by-line reader (Python's float), digit for digit, at the writers' 6 decimals
    and at full precision."""
    rng = np.random.default_rng(7)
    pts = rng.normal(0, 60, (400, 20, 3)) * 10.0 ** rng.integers(-3, 3, (400, 20, 3))
    p = tmp_path / "plain.trc"
    write_trc(p, Recording([f"M{j}" for j in range(20)], pts, 100.0))
    lines = _lines(p)
    for i in range(6, len(lines)):
        f = lines[i].rstrip("\n").split("\t")
        lines[i] = "\t".join(f[:2] + [fmt % v for v in pts[i - 6].ravel()]) + "\n"
    p.write_text("".join(lines))
    monkeypatch.setattr(base, "FAST_TEXT", False)
    exact = read_trc(p).points
    calls = []
    real = trc_blocks._parse_plain
    monkeypatch.setattr(trc_blocks, "_parse_plain",
                        lambda c, n: calls.append(1) or real(c, n))
    fast = {"pandas": trc_blocks._pandas, "loadtxt": trc_blocks._loadtxt,
            "arrow": trc_blocks._arrow}[parser]
    took = []
    monkeypatch.setattr(trc_blocks, f"_{parser}", lambda c, n: took.append(1) or fast(c, n))
    _, pts_b, n = _read_blocks(p, 20_000)
    assert n > 3 and len(calls) == n and len(took) == n
    if fmt == "%.6f":
        np.testing.assert_array_equal(pts_b, exact)
    else:  # the 17-digit strings are Python's own: parsing gives the very same floats
        np.testing.assert_array_equal(exact, pts)
        np.testing.assert_array_equal(pts_b if parser == "loadtxt" else exact, pts)


def _block_threads():
    import threading

    return [t for t in threading.enumerate() if t.name == "trc-blocks"]


def test_the_next_block_is_parsed_ahead_and_stops_with_the_caller(tmp_path):
    """Blocks are parsed in a thread one block ahead: the caller that stops after one block
    leaves no thread behind and the file closed; an error of a later block comes after the
    blocks before it."""
    p = _file(tmp_path)
    it = open_trc_blocks(p).blocks(300)
    first, _ = next(it)
    assert first == 0 and len(_block_threads()) == 1
    it.close()
    assert _block_threads() == []
    _edit(p, 250, CASES["short line"][1])
    got = []
    with pytest.raises(InputError, match="line 250"):
        for a, blk in open_trc_blocks(p).blocks(300):
            got.append(a + len(blk))
    assert got and got[-1] < 250 - 6 and _block_threads() == []
