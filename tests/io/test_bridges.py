"""Round trips through pyomeca (xarray Markers) and kineticstoolkit (TimeSeries): labels, rate
and values kept, each library reading our C3D on its own and agreeing with facemotion's reader."""

import kineticstoolkit as ktk
import numpy as np
import pyomeca
import pytest

from facemotion.errors import InputError
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording


def take(F=40, n=5, seed=0):
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 30, (F, n, 3))
    pts[3:6, 1] = np.nan
    filled = np.zeros((F, n), bool)
    filled[10:12, 2] = True
    return Recording([f"M{j}" for j in range(n)], pts, 120.0, "take", filled)


def test_pyomeca_round_trip():
    rec = take()
    m = rec.to_xarray()
    assert m.dims == ("axis", "channel", "time") and m.name == "markers"
    assert list(m.channel.values) == rec.labels and m.attrs["rate"] == 120.0
    # pyomeca's own constructor gives the same layout
    ref = pyomeca.Markers(rec.points.transpose(2, 1, 0), channels=rec.labels, time=rec.time_s)
    np.testing.assert_array_equal(m.values, ref.values)
    assert list(m.axis.values) == list(ref.axis.values)
    back = Recording.from_xarray(m)
    assert back.labels == rec.labels and back.rate == rec.rate
    np.testing.assert_array_equal(back.points, rec.points)
    np.testing.assert_array_equal(back.filled, rec.filled)
    # pyomeca's processing runs on it
    assert m.meca.abs().shape == m.shape


def test_pyomeca_reads_our_c3d_like_we_do(tmp_path):
    rec = take()
    write_c3d(tmp_path / "t.c3d", rec)
    m = pyomeca.Markers.from_c3d(str(tmp_path / "t.c3d"))
    ours = read_c3d(tmp_path / "t.c3d")
    back = Recording.from_xarray(m)
    assert back.labels == ours.labels and back.rate == pytest.approx(ours.rate)
    np.testing.assert_allclose(back.points, ours.points, atol=1e-4, equal_nan=True)
    # metres in, mm out
    m_m = m.copy()
    m_m[:3] = m_m[:3] / 1000.0
    m_m.attrs["units"] = "m"
    np.testing.assert_allclose(Recording.from_xarray(m_m).points, ours.points, atol=1e-4,
                               equal_nan=True)


def test_kineticstoolkit_round_trip(tmp_path):
    rec = take()
    ts = rec.to_timeseries()
    assert sorted(ts.data) == sorted(rec.labels)
    assert ts.info["M0"]["Unit"] == "m"
    np.testing.assert_allclose(ts.data["M3"][:, :3], rec.points[:, 3] / 1000.0)
    assert ts.get_sample_rate() == pytest.approx(120.0)
    back = Recording.from_timeseries(ts)
    assert back.labels == rec.labels and back.rate == pytest.approx(120.0)
    np.testing.assert_allclose(back.points, rec.points, rtol=1e-12, equal_nan=True)
    # kineticstoolkit's own C3D reader on our file
    write_c3d(tmp_path / "t.c3d", rec)
    points = ktk.read_c3d(str(tmp_path / "t.c3d"), convert_point_unit=True)["Points"]
    from_ktk = Recording.from_timeseries(points, labels=rec.labels)
    np.testing.assert_allclose(from_ktk.points, read_c3d(tmp_path / "t.c3d").points,
                               atol=1e-4, equal_nan=True)
    assert from_ktk.rate == pytest.approx(120.0)


def test_bad_inputs_name_the_problem():
    rec = take()
    with pytest.raises(InputError, match="dims \\(axis, channel, time\\)"):
        Recording.from_xarray(rec.to_xarray().rename({"channel": "marker"}))
    ts = rec.to_timeseries()
    with pytest.raises(InputError, match="no data 'nope'"):
        Recording.from_timeseries(ts, labels=["nope"])
    ts.time[5] += 0.001
    with pytest.raises(InputError, match="not evenly spaced"):
        Recording.from_timeseries(ts)
