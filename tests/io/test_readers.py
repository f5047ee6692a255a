"""Readers and writers: round trips, independent files (raw ezc3d, hand-written text), errors."""


import ezc3d
import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording
from facemotion.io.registry import read_recording
from facemotion.io.trc import read_trc, trc_frame_count, write_trc
from facemotion.io.wide_csv import read_csv, write_csv


def sample_recording(F=30, n=4, seed=1, rate=120.0):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-300, 300, size=(F, n, 3))
    pts[3:7, 1, :] = np.nan  # a gap
    pts[:, 3, :] = np.nan  # a marker missing in every frame: kept, not an error
    return Recording(["Chin", "Mouth_Up", "L017", "Nose Tip"], pts, rate, source="synthetic")


def raw_c3d(path, labels, xyz_fmn, rate, units="mm", residuals=None):
    """An independent C3D writer: ezc3d calls only. xyz_fmn: (frames, markers, 3)."""
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = [units]
    F, n, _ = xyz_fmn.shape
    pts = np.ones((4, n, F))
    pts[:3] = xyz_fmn.transpose(2, 1, 0)
    c["data"]["points"] = pts
    if residuals is not None:
        c["data"]["meta_points"]["residuals"] = residuals.T[None].astype(float)
        c["data"]["meta_points"]["camera_masks"] = np.zeros((7, n, F), dtype=bool)
    c.write(str(path))


def assert_same(a: Recording, b: Recording, atol):
    assert a.labels == b.labels
    assert a.rate == pytest.approx(b.rate)
    np.testing.assert_array_equal(np.isnan(a.points), np.isnan(b.points))
    np.testing.assert_allclose(a.points, b.points, atol=atol, equal_nan=True)


# ------------------------------------------------------------------------------------------ C3D

def test_c3d_round_trip(tmp_path):
    rec = sample_recording()
    write_c3d(tmp_path / "a.c3d", rec)
    back = read_c3d(tmp_path / "a.c3d")
    assert_same(back, rec, atol=1e-4)  # C3D stores float32
    assert back.source.endswith("a.c3d")
    assert not back.filled.any()
    assert [p.name for p in tmp_path.iterdir()] == ["a.c3d"]  # no temporary left behind


def test_c3d_written_by_raw_ezc3d_in_cm(tmp_path):
    rng = np.random.default_rng(2)
    xyz = rng.uniform(-30, 30, size=(12, 3, 3))  # cm
    raw_c3d(tmp_path / "cm.c3d", ["Chin ", "Mouth_Up", "ForeHead_M"], xyz, 60.0, units="cm")
    rec = read_recording(tmp_path / "cm.c3d", "c3d")
    assert rec.labels == ["Chin", "Mouth_Up", "ForeHead_M"]
    assert rec.rate == 60.0
    np.testing.assert_allclose(rec.points, 10 * xyz, rtol=1e-6)
    assert (rec.units, rec.units_source) == ("cm", "file")
    # the file's own units win over the sheet's (validation reports the conflict)
    back = read_c3d(tmp_path / "cm.c3d", units="m")
    np.testing.assert_allclose(back.points, 10 * xyz, rtol=1e-6)
    assert (back.units, back.units_source) == ("cm", "file")


def test_c3d_without_units_takes_the_sheets(tmp_path):
    xyz = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3) + 1
    raw_c3d(tmp_path / "n.c3d", ["a", "b"], xyz, 100.0, units="")
    with pytest.raises(InputError, match=r"n\.c3d.*POINT:UNITS is missing"):
        read_c3d(tmp_path / "n.c3d")
    rec = read_c3d(tmp_path / "n.c3d", units="cm")
    np.testing.assert_allclose(rec.points, 10 * xyz, rtol=1e-6)
    assert (rec.units, rec.units_source) == ("cm", "sheet")


@pytest.mark.parametrize("unit,factor", [("mm", 1.0), ("m", 1000.0), ("in", 25.4)])
def test_c3d_units(tmp_path, unit, factor):
    xyz = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3) + 1
    raw_c3d(tmp_path / "u.c3d", ["a", "b"], xyz, 100.0, units=unit)
    np.testing.assert_allclose(read_c3d(tmp_path / "u.c3d").points, factor * xyz, rtol=1e-6)


def test_c3d_invalid_samples_are_nan(tmp_path):
    xyz = np.full((5, 3, 3), 7.0)
    xyz[2, 1] = 0.0  # (0, 0, 0) with residual 0: exporters' "no data"
    residuals = np.zeros((5, 3))
    residuals[3, 0] = -1.0  # invalid flag with real-looking coordinates
    residuals[1, 2] = -1.0
    raw_c3d(tmp_path / "inv.c3d", ["a", "b", "c"], xyz, 50.0, residuals=residuals)
    rec = read_c3d(tmp_path / "inv.c3d")
    missing = np.isnan(rec.points).all(axis=2)
    expected = np.zeros((5, 3), dtype=bool)
    expected[2, 1] = expected[3, 0] = expected[1, 2] = True
    np.testing.assert_array_equal(missing, expected)
    assert not np.isnan(rec.points[~expected]).any()


def test_c3d_unknown_units(tmp_path):
    raw_c3d(tmp_path / "f.c3d", ["a", "b"], np.ones((2, 2, 3)), 100.0, units="furlong")
    with pytest.raises(InputError, match=r"f\.c3d.*furlong"):
        read_c3d(tmp_path / "f.c3d")


def test_c3d_not_a_c3d(tmp_path):
    (tmp_path / "x.c3d").write_text("hello")
    with pytest.raises(InputError, match=r"x\.c3d"):
        read_c3d(tmp_path / "x.c3d")


def test_missing_file_and_unknown_format(tmp_path):
    with pytest.raises(InputError, match=r"nope\.trc.*not found"):
        read_recording(tmp_path / "nope.trc", "trc")
    with pytest.raises(InputError, match=r"a\.bvh.*'bvh'"):
        read_recording(tmp_path / "a.bvh", "bvh")


# ------------------------------------------------------------------------------------------ TRC

def test_trc_round_trip(tmp_path):
    rec = sample_recording(rate=59.94)
    write_trc(tmp_path / "a.trc", rec)
    assert_same(read_trc(tmp_path / "a.trc"), rec, atol=1e-6)
    assert [p.name for p in tmp_path.iterdir()] == ["a.trc"]


HAND_TRC = (
    "PathFileType\t4\t(X/Y/Z)\thand.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\t"
    "OrigNumFrames\n"
    "25.00\t25.00\t3\t2\tm\t25.00\t1\t3\n"
    "Frame#\tTime\tL000\t\t\tL017\t\t\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
    "\n"
    "1\t0.00000\t0.1\t0.2\t0.3\t1.0\t2.0\t3.0\n"
    "2\t0.04000\t0.1\t0.2\t0.3\t\t\t\n"
    "3\t0.08000\t0.4\t0.5\t0.6\t\t\t\t\n"  # a trailing empty field beyond the last: allowed
)


def test_trc_hand_written(tmp_path):
    (tmp_path / "hand.trc").write_text(HAND_TRC)
    rec = read_recording(tmp_path / "hand.trc", "trc")
    assert rec.labels == ["L000", "L017"]
    assert rec.rate == 25.0
    expected = np.array([[[100, 200, 300], [1000, 2000, 3000]],
                         [[100, 200, 300], [np.nan] * 3],
                         [[400, 500, 600], [np.nan] * 3]], dtype=float)
    np.testing.assert_allclose(rec.points, expected, equal_nan=True)
    # the header's units win over the sheet's
    np.testing.assert_allclose(read_trc(tmp_path / "hand.trc", units="mm").points,
                               expected, equal_nan=True)
    # no Units in the header: the sheet's apply
    (tmp_path / "nounits.trc").write_text(HAND_TRC.replace("\t3\t2\tm\t", "\t3\t2\t\t"))
    with pytest.raises(InputError, match=r"nounits\.trc.*no Units"):
        read_trc(tmp_path / "nounits.trc")
    np.testing.assert_allclose(read_trc(tmp_path / "nounits.trc", units="cm").points,
                               expected / 100, equal_nan=True)


@pytest.mark.parametrize("bad,match", [
    (("\t3\t2\tm", "\t4\t2\tm"), "NumFrames=4"),
    (("\t3\t2\tm", "\t3\t3\tm"), "NumMarkers=3"),
    (("\t3\t2\tm", "\t3\t2\tparsec"), "parsec"),
    (("0.4\t0.5", "0.4\tabc"), "'abc'.*line 9 field 4"),
    # a field (and its tab) missing: every later value would move to another axis
    (("0.1\t0.2\t0.3\t1.0", "0.1\t0.3\t1.0"), "line 7 has 7 fields.*declares 8"),
    (("0.6\t\t\t\t\n", "0.6\n"), "line 9 has 5 fields"),
    (("2\t0.04000\t0.1\t0.2\t0.3\t\t\t\n", ""), "NumFrames=3.*2 data lines"),
    (("0.6\t\t\t\t\n", "0.6\t\t\t\tx\n"), "line 9 has 9 fields"),
    # the file ends inside its last line
    (("0.6\t\t\t\t\n", "0.6\t\t\t\t"), "line 9, the last one, has no line end"),
    # time off the DataRate grid: a dropped, repeated or reordered line
    (("2\t0.04000", "2\t0.08000"), "line 8: Time 0.08.*grid"),
    (("3\t0.08000", "2\t0.08000"), "line 9: Frame# 2 does not follow 2"),
    (("25.00\t25.00\t3", "50.00\t50.00\t3"), "line 8: Time 0.04.*50 Hz"),
    (("\t3\t2\tm", "\t3.5\t2\tm"), "not numeric"),
])
def test_trc_errors(tmp_path, bad, match):
    (tmp_path / "bad.trc").write_text(HAND_TRC.replace(*bad))
    with pytest.raises(InputError, match=r"bad\.trc.*" + match):
        read_trc(tmp_path / "bad.trc")


def test_trc_frame_count_from_the_header_is_the_readers_count(tmp_path):
    """The parse-time count (header only) equals the frames read, on GRID's TRCs and a
    hand-written file; a header that lies about NumFrames is refused by the reader."""
    (tmp_path / "hand.trc").write_text(HAND_TRC)
    shared = SHARED_DATA
    files = [tmp_path / "hand.trc", *sorted((shared / "grid").glob("*.trc"))[:2]]
    assert len(files) == 3
    for f in files:
        assert trc_frame_count(f) == read_trc(f).n_frames
    (tmp_path / "lies.trc").write_text(HAND_TRC.replace("\t3\t2\tm", "\t4\t2\tm"))
    assert trc_frame_count(tmp_path / "lies.trc") == 4
    with pytest.raises(InputError, match="NumFrames=4"):
        read_trc(tmp_path / "lies.trc")
    with pytest.raises(InputError, match=r"nounits\.trc.*no Units"):
        (tmp_path / "nounits.trc").write_text(HAND_TRC.replace("\t3\t2\tm\t", "\t3\t2\t\t"))
        trc_frame_count(tmp_path / "nounits.trc")


# ------------------------------------------------------------------------------------------ CSV

def test_csv_round_trip(tmp_path):
    rec = sample_recording(rate=120.0)
    write_csv(tmp_path / "a.csv", rec)
    assert_same(read_csv(tmp_path / "a.csv"), rec, atol=1e-6)


def test_csv_hand_written(tmp_path):
    (tmp_path / "h.csv").write_text("time,Mouth_Up_x,Mouth_Up_y,Mouth_Up_z,40_x,40_y,40_z\n"
                                    "0.0,1,2,3,4,5,6\n"
                                    "0.01,1.5,2.5,3.5,,,\n"
                                    "0.02,2,3,4,7,8,9\n")
    rec = read_recording(tmp_path / "h.csv", "csv")
    assert rec.labels == ["Mouth_Up", "40"]
    assert rec.rate == 100.0
    np.testing.assert_allclose(rec.points[:, 0], [[1, 2, 3], [1.5, 2.5, 3.5], [2, 3, 4]])
    assert np.isnan(rec.points[1, 1]).all()
    np.testing.assert_allclose(rec.points[2, 1], [7, 8, 9])
    np.testing.assert_allclose(read_csv(tmp_path / "h.csv", units="cm").points[2, 1],
                               [70, 80, 90])


def test_csv_non_uniform_time(tmp_path):
    (tmp_path / "t.csv").write_text("time,a_x,a_y,a_z\n0,1,2,3\n0.01,1,2,3\n0.03,1,2,3\n")
    with pytest.raises(InputError, match=r"t\.csv.*'time'.*uniform"):
        read_csv(tmp_path / "t.csv")


@pytest.mark.parametrize("header,match", [
    ("time,a_x,a_y", "a_z"),
    ("time,a_x,a_y,a_z,b", "'b'"),
    ("t,a_x,a_y,a_z", "'time'"),
])
def test_csv_bad_header(tmp_path, header, match):
    n = header.count(",")
    (tmp_path / "b.csv").write_text(header + "\n" + ",".join(["0"] * (n + 1)) + "\n"
                                    + ",".join(["0.1"] * (n + 1)) + "\n")
    with pytest.raises(InputError, match=r"b\.csv.*" + match):
        read_csv(tmp_path / "b.csv")


def test_csv_row_with_a_field_missing(tmp_path):
    good = "time,a_x,a_y,a_z,b_x,b_y,b_z\n0,1,2,3,4,5,6\n0.01,1,2,3,,,\n0.02,1,2,3,4,5,6\n"
    (tmp_path / "f.csv").write_text(good.replace("0.01,1,2,3,,,", "0.01,1,2,3,,"))
    with pytest.raises(InputError, match=r"f\.csv: line 3 has 6 fields but the header has 7"):
        read_csv(tmp_path / "f.csv")
    (tmp_path / "g.csv").write_text(good.replace("0.01,1,2,3,,,", "0.01,1,2,3,,,,"))
    with pytest.raises(InputError, match=r"g\.csv: line 3 has 8 fields"):
        read_csv(tmp_path / "g.csv")
    (tmp_path / "h.csv").write_text(good[:-1])  # the last line cut
    with pytest.raises(InputError, match=r"h\.csv: line 4, the last one, has no line end"):
        read_csv(tmp_path / "h.csv")


def test_messages_quote_only_a_short_token(tmp_path):
    secret = "root:$6$abcdefghijklmnopqrstuvwxyz0123456789:19000:0:99999:7:::"
    (tmp_path / "shadow").write_text(secret + "\n" + secret + "\n")
    with pytest.raises(InputError) as e:
        read_csv(tmp_path / "shadow")
    msg = str(e.value)
    assert "first column must be 'time'" in msg and "\n" not in msg
    assert secret[:8] not in msg and f"got a text of {len(secret)} characters" in msg
    trc = HAND_TRC.replace("0.4\t0.5", "0.4\t" + secret.replace(":", ""))
    (tmp_path / "s.trc").write_text(trc)
    with pytest.raises(InputError) as e:
        read_trc(tmp_path / "s.trc")
    assert secret.replace(":", "")[:20] not in str(e.value)


def test_directory_is_not_a_recording(tmp_path):
    (tmp_path / "takes.trc").mkdir()
    with pytest.raises(InputError, match=r"takes\.trc: is a directory, not a recording file"):
        read_recording(tmp_path / "takes.trc", "trc")


# ------------------------------------------------------------------------------ C3D truncation

def test_c3d_layout_matches_ezc3d_on_real_files():
    """The header/parameter parse against ezc3d's, on every C3D variant of the shared data
    (Intel and DEC, integer and float storage, analog channels, first frame > 1)."""

    from facemotion.io.c3d import c3d_layout

    root = SHARED_DATA
    files = sorted(root.glob("*/*.c3d"))
    assert len(files) >= 8
    for f in files:
        c = ezc3d.c3d(str(f))
        lay = c3d_layout(f)
        P = c["parameters"]
        assert lay.frames == c["data"]["points"].shape[2]
        assert lay.points == c["data"]["points"].shape[1]
        n_analog = c["data"]["analogs"].shape[1] * c["data"]["analogs"].shape[2]
        assert lay.analog_per_frame * lay.frames == n_analog
        assert lay.float_storage == (float(P["POINT"]["SCALE"]["value"][0]) < 0)
        assert lay.data_start == (int(P["POINT"]["DATA_START"]["value"][0]) - 1) * 512
        assert lay.size <= f.stat().st_size < lay.size + 512


@pytest.mark.parametrize("name", ["animface/animface_jaw.c3d",
                                  "c3d_suite/c3dorg_sample01_Eb015pi.c3d",
                                  "c3d_suite/c3dorg_sample02_dec_int.c3d",
                                  "c3d_suite/ktk_tennis_serve_2players.c3d"])
@pytest.mark.parametrize("cut", [1, 700, 5000])
def test_truncated_c3d_is_an_error(tmp_path, name, cut):

    from facemotion.io.c3d import c3d_layout

    root = SHARED_DATA
    raw = (root / name).read_bytes()
    padding = len(raw) - c3d_layout(root / name).size
    (tmp_path / "cut.c3d").write_bytes(raw[:-cut])
    if cut <= padding:  # only padding lost: the same data
        np.testing.assert_array_equal(read_c3d(tmp_path / "cut.c3d").points,
                                      read_c3d(root / name).points)
    else:
        with pytest.raises(InputError, match=r"cut\.c3d: C3D file is cut short.*bytes"):
            read_c3d(tmp_path / "cut.c3d")


def test_c3d_with_more_frames_than_declared(tmp_path):
    rec = sample_recording(F=20)
    write_c3d(tmp_path / "a.c3d", rec)
    raw = (tmp_path / "a.c3d").read_bytes()
    (tmp_path / "b.c3d").write_bytes(raw + bytes(2048))
    with pytest.raises(InputError, match=r"b\.c3d: C3D file holds .* bytes after the 20 frames"):
        read_c3d(tmp_path / "b.c3d")
    with pytest.raises(InputError, match="without frames"):
        write_c3d(tmp_path / "empty.c3d", Recording(["a", "b"], np.zeros((0, 2, 3)), 100.0))
    long = Recording(["a", "b"], np.zeros((65536, 2, 3)), 100.0)
    with pytest.raises(InputError, match="65536 frames cannot be written to C3D"):
        write_c3d(tmp_path / "long.c3d", long)
