"""Property-based tests of the readers (hypothesis).

* A random recording written in each format and read back is the same recording.
* A random truncation of a file, or (text formats) the deletion of one field, never reads back
  as a different valid recording: the reader raises InputError, or returns the same recording
  (a cut that only lost C3D padding, a deleted field of a header line the reader does not use).
  A CSV has no frame count, so a cut exactly at a line end reads back as the first frames of
  the original (a prefix); every other cut is an error.
"""

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from facemotion.errors import InputError
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording
from facemotion.io.trc import read_trc, write_trc
from facemotion.io.wide_csv import read_csv, write_csv

READ = {"c3d": read_c3d, "trc": read_trc, "csv": read_csv}
WRITE = {"c3d": write_c3d, "trc": write_trc, "csv": write_csv}
# absolute tolerance of a round trip: C3D stores float32, the text formats print 6 decimals
ATOL = {"c3d": 1e-4, "trc": 1e-6, "csv": 1e-6}
SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])

label = st.text(alphabet="ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_",
                min_size=1, max_size=8)


@st.composite
def recordings(draw):
    n = draw(st.integers(1, 5))
    frames = draw(st.integers(2, 12))
    labels = draw(st.lists(label, min_size=n, max_size=n, unique=True))
    # rates every writer stores exactly: TRC prints 6 significant digits, CSV times 9
    rate = draw(st.sampled_from([25.0, 50.0, 59.94, 60.0, 100.0, 120.0, 240.0, 1000.0]))
    values = draw(st.lists(st.floats(-900, 900, allow_nan=False).filter(lambda v: v != 0),
                           min_size=frames * n * 3, max_size=frames * n * 3))
    pts = np.round(np.array(values).reshape(frames, n, 3), 3)
    pts[pts == 0] = 0.5  # (0, 0, 0) is C3D's "no data"
    missing = draw(st.lists(st.booleans(), min_size=frames * n, max_size=frames * n))
    pts[np.array(missing).reshape(frames, n)] = np.nan
    return Recording(labels, pts, rate, source="hypothesis")


def assert_same(a: Recording, b: Recording, atol: float) -> None:
    assert a.labels == b.labels
    assert a.rate == b.rate or abs(a.rate - b.rate) < 1e-6 * b.rate
    np.testing.assert_array_equal(np.isnan(a.points), np.isnan(b.points))
    np.testing.assert_allclose(a.points, b.points, atol=atol, rtol=0)


def written(rec: Recording, fmt: str) -> bytes:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"take.{fmt}"
        WRITE[fmt](path, rec)
        return path.read_bytes()


def read_bytes(data: bytes, fmt: str):
    """The recording ``data`` reads as, or the InputError it raises (anything else fails)."""
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"take.{fmt}"
        path.write_bytes(data)
        try:
            return READ[fmt](path)
        except InputError as e:
            assert "\n" not in str(e)
            return e


@SETTINGS
@given(rec=recordings(), fmt=st.sampled_from(sorted(READ)))
def test_round_trip(rec, fmt):
    back = read_bytes(written(rec, fmt), fmt)
    assert isinstance(back, Recording), back
    assert_same(back, rec, ATOL[fmt])


@SETTINGS
@given(rec=recordings(), fmt=st.sampled_from(sorted(READ)), where=st.floats(0, 1))
def test_truncation_never_reads_as_another_recording(rec, fmt, where):
    data = written(rec, fmt)
    cut = int(where * (len(data) - 1))  # keep 0 .. len-1 bytes
    back = read_bytes(data[:cut], fmt)
    if isinstance(back, InputError):
        return
    original = read_bytes(data, fmt)
    if fmt == "csv" and back.n_frames < original.n_frames:  # a cut at a line end: a prefix
        assert data[:cut].endswith(b"\n")
        prefix = Recording(original.labels, original.points[:back.n_frames], original.rate)
        assert_same(back, prefix, 0)
    else:
        assert_same(back, original, 0)


@SETTINGS
@given(rec=recordings(), fmt=st.sampled_from(["trc", "csv"]), line_at=st.floats(0, 1),
       field_at=st.floats(0, 1))
def test_deleting_a_field_never_reads_as_another_recording(rec, fmt, line_at, field_at):
    data = written(rec, fmt).decode()
    lines = data.split("\n")[:-1]
    sep = "\t" if fmt == "trc" else ","
    i = int(line_at * (len(lines) - 1))
    fields = lines[i].split(sep)
    if len(fields) < 2:
        return
    del fields[int(field_at * (len(fields) - 1))]
    lines[i] = sep.join(fields)
    back = read_bytes(("\n".join(lines) + "\n").encode(), fmt)
    if isinstance(back, InputError):
        return
    assert_same(back, read_bytes(data.encode(), fmt), 0)
