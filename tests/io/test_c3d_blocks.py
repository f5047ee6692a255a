"""The C3D block reader against ezc3d (through read_c3d) on lab-written files: the same
points, labels, rate and units, wherever the blocks cut the data section."""

import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.stream_scan import WholeTake, take_blocks
from facemotion.io.c3d import read_c3d
from facemotion.io.c3d_blocks import open_c3d_blocks

SUITE = Path(__file__).resolve().parents[3] / "shared" / "data" / "c3d_suite"
INTEL = {"c3dorg_sample01_Eb015pi.c3d": "integer", "c3dorg_sample02_pc_real.c3d": "float",
         "ktk_racing_static.c3d": "float", "ktk_tennis_serve_2players.c3d": "float"}


def _blocks(p, block_bytes):
    cb = open_c3d_blocks(p)
    got = list(cb.blocks(block_bytes))
    assert [a for a, _ in got] == list(np.cumsum([0] + [len(b) for _, b in got[:-1]]))
    return cb, np.concatenate([b for _, b in got]), len(got)


@pytest.mark.parametrize("name", sorted(INTEL))
@pytest.mark.parametrize("block_bytes", [5000, 10**8])
def test_blocks_give_ezc3ds_reading(name, block_bytes):
    p = SUITE / name
    rec = read_c3d(p)
    cb, pts, n = _blocks(p, block_bytes)
    assert (n > 1) == (block_bytes == 5000)
    assert cb.layout.float_storage == (INTEL[name] == "float")
    assert (cb.labels, cb.rate, cb.units, cb.units_source) == (
        rec.labels, rec.rate, rec.units, rec.units_source)
    np.testing.assert_array_equal(pts, rec.points)
    assert np.isfinite(pts).any() and cb.n_frames == rec.n_frames


def test_an_invalid_residual_is_a_gap_in_both_readers(tmp_path):
    """The comparison can fail: a negative residual written into one sample makes it missing
    in ezc3d's reading and in the blocks, and only there."""
    src = SUITE / "c3dorg_sample02_pc_real.c3d"
    p = tmp_path / "edited.c3d"
    shutil.copy(src, p)
    p.chmod(0o644)
    cb = open_c3d_blocks(p)
    lay = cb.layout
    frame, point = 40, int(cb.kept[3])
    at = lay.data_start + 4 * (frame * (4 * lay.points + lay.analog_per_frame) + 4 * point + 3)
    data = bytearray(p.read_bytes())
    data[at:at + 4] = struct.pack("<f", -1.0)  # the writers' "invalid" residual word
    p.write_bytes(bytes(data))
    before = read_c3d(src).points
    after = read_c3d(p).points
    _, pts, _ = _blocks(p, 7000)
    assert np.isfinite(before[frame, 3]).all() and np.isnan(after[frame, 3]).all()
    np.testing.assert_array_equal(pts, after)
    assert not np.array_equal(pts, before, equal_nan=True)


def test_other_processors_are_refused_in_one_line_and_read_whole():
    p = SUITE / "c3dorg_sample02_dec_int.c3d"
    with pytest.raises(InputError, match=r"dec_int\.c3d: C3D written for a DEC processor; "
                                         r"the block reader reads Intel files only"):
        open_c3d_blocks(p)
    whole = take_blocks(p, "c3d")
    assert isinstance(whole, WholeTake)
    np.testing.assert_array_equal(whole.rec.points, read_c3d(p).points)
    assert not isinstance(take_blocks(SUITE / "ktk_racing_static.c3d", "c3d"), WholeTake)


@pytest.mark.parametrize("name", sorted(p.name for p in SUITE.glob("*.c3d")))
def test_labels_without_the_data_are_read_c3ds(name):
    """The labels the streamed loader checks first: from the parameter section for Intel
    files (no data read), from the whole file for the others; read_c3d's either way."""
    from facemotion.io.registry import get_format

    p = SUITE / name
    assert get_format("c3d").labels(p) == read_c3d(p).labels
