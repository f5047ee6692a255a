"""The in-memory form of one take (one sentence): labelled 3-D marker trajectories in mm."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from facemotion.errors import InputError


def finite_samples(points: np.ndarray) -> np.ndarray:
    """(..., markers) bool, True where all three coordinates of a sample (last axis, length
    3) are finite: ``np.isfinite(points).all(axis=-1)`` in three strided passes, about ten
    times faster than a reduction over an axis of length 3."""
    return (np.isfinite(points[..., 0]) & np.isfinite(points[..., 1])
            & np.isfinite(points[..., 2]))


@dataclass
class Recording:
    """One take of labelled marker trajectories.

    points: (frames, markers, 3) float64 in millimetres; NaN marks a missing sample.
    filled: (frames, markers) bool, True where a sample was filled (by the recording's
        producer or by our gap filling) rather than measured.
    units: the units the file's numbers were in (converted to mm on reading) and
    units_source: where they were declared: "file" (the file's own header), "sheet" (the
        subject sheet, for a file that does not say) or "default" (mm, for a CSV).
    """

    labels: list[str]
    points: np.ndarray
    rate: float
    source: str = ""
    filled: np.ndarray | None = field(default=None)
    units: str = "mm"
    units_source: str = "default"

    def __post_init__(self) -> None:
        self.labels = [str(label) for label in self.labels]
        # C order always: the same samples give the same sums whichever reader made them
        self.points = np.ascontiguousarray(self.points, dtype=float)
        if self.points.ndim != 3 or self.points.shape[2] != 3:
            raise InputError(f"{self.source or 'recording'}: points must be (frames, markers, 3), "
                             f"got shape {self.points.shape}")
        if self.points.shape[1] != len(self.labels):
            raise InputError(f"{self.source or 'recording'}: {len(self.labels)} labels but "
                             f"{self.points.shape[1]} markers in the data")
        if len(set(self.labels)) != len(self.labels):
            dup = sorted({x for x in self.labels if self.labels.count(x) > 1})
            raise InputError(f"{self.source or 'recording'}: duplicate marker labels {dup}")
        if not np.isfinite(self.rate) or self.rate <= 0:
            raise InputError(f"{self.source or 'recording'}: frame rate must be positive, "
                             f"got {self.rate}")
        if self.filled is None:
            self.filled = np.zeros(self.points.shape[:2], dtype=bool)
        else:
            self.filled = np.ascontiguousarray(self.filled, dtype=bool)
            if self.filled.shape != self.points.shape[:2]:
                raise InputError(f"{self.source or 'recording'}: fill mask shape "
                                 f"{self.filled.shape} != {self.points.shape[:2]}")

    @property
    def n_frames(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_markers(self) -> int:
        return int(self.points.shape[1])

    def index(self, label: str) -> int:
        """Column of a marker, with an error naming the marker and the file if absent."""
        try:
            return self.labels.index(str(label))
        except ValueError:
            raise InputError(f"{self.source or 'recording'}: marker {label!r} not found "
                             f"(have {len(self.labels)} markers: {', '.join(self.labels[:8])}"
                             f"{', ...' if len(self.labels) > 8 else ''})") from None

    @property
    def time_s(self) -> np.ndarray:
        """Time of each frame (s) from the start of the take."""
        return np.arange(self.n_frames) / self.rate

    def to_frame(self):
        """The trajectories as a pandas DataFrame: index ``time_s``, columns (marker, axis), mm.

        Missing samples are NaN; the fill mask is not included (see ``filled``).
        """
        import pandas as pd

        columns = pd.MultiIndex.from_product([self.labels, ["x", "y", "z"]],
                                             names=["marker", "axis"])
        return pd.DataFrame(self.points.reshape(self.n_frames, -1), columns=columns,
                            index=pd.Index(self.time_s, name="time_s"))

    def to_xarray(self):
        """The trajectories as pyomeca's ``Markers``: an ``xarray.DataArray`` named "markers"
        with dims (axis, channel, time), axis x, y, z and the homogeneous "ones" row, channel
        the labels, time in s, attrs rate (Hz) and units "mm" (pyomeca's ``from_c3d`` layout).
        Missing samples are NaN; the fill mask travels as the attr ``filled`` (channel x time,
        as a nested list of 0/1).  Needs xarray (the 'pyomeca' extra)."""
        import xarray as xr

        data = np.ones((4, self.n_markers, self.n_frames))
        data[:3] = self.points.transpose(2, 1, 0)
        attrs = {"rate": float(self.rate), "units": "mm", "first_frame": 0,
                 "last_frame": self.n_frames - 1}
        if self.source:
            attrs["source"] = self.source
        if self.filled.any():
            attrs["filled"] = self.filled.T.astype(int).tolist()
        return xr.DataArray(data, dims=("axis", "channel", "time"), name="markers",
                            coords={"axis": ["x", "y", "z", "ones"], "channel": self.labels,
                                    "time": self.time_s}, attrs=attrs)

    @classmethod
    def from_xarray(cls, markers, source: str = "") -> Recording:
        """A recording from pyomeca's ``Markers`` (dims axis, channel, time; axis x, y, z
        first): labels from ``channel``, the rate from the ``rate`` attr (else from ``time``),
        coordinates converted to mm from the ``units`` attr (default mm)."""
        from facemotion.io.base import unit_scale

        where = source or "markers"
        dims = tuple(getattr(markers, "dims", ()))
        if set(dims) != {"axis", "channel", "time"}:
            raise InputError(f"{where}: expected an xarray DataArray with dims (axis, channel, "
                             f"time) as pyomeca's Markers, got {dims or type(markers).__name__}")
        da = markers.transpose("axis", "channel", "time")
        axes = [str(a) for a in da.coords["axis"].values] if "axis" in da.coords else []
        if axes[:3] != ["x", "y", "z"]:
            raise InputError(f"{where}: axis coordinates must start x, y, z, got {axes[:3]}")
        rate = _rate_of(da, where)
        scale = unit_scale(str(da.attrs.get("units", "mm")), f"{where}: units")
        points = np.asarray(da.values[:3], dtype=float).transpose(2, 1, 0) * scale
        filled = da.attrs.get("filled")
        filled = None if filled is None else np.asarray(filled, dtype=bool).T
        labels = [str(c) for c in da.coords["channel"].values]
        return cls(labels, points, rate, source or str(da.attrs.get("source", "")), filled)

    def to_timeseries(self, units: str = "m"):
        """The trajectories as a kineticstoolkit ``TimeSeries``: one (frames, 4) homogeneous
        array per marker (x, y, z, 1), in ``units`` (kineticstoolkit's own convention is m;
        stated in each marker's data_info 'Unit').  Needs the 'kineticstoolkit' extra."""
        import kineticstoolkit as ktk

        from facemotion.io.base import unit_scale

        scale = unit_scale(units, "units")
        ts = ktk.TimeSeries(time=self.time_s)
        for j, label in enumerate(self.labels):
            data = np.ones((self.n_frames, 4))
            data[:, :3] = self.points[:, j] / scale
            ts = ts.add_data(label, data).add_info(label, "Unit", units)
        return ts

    @classmethod
    def from_timeseries(cls, ts, labels: list[str] | None = None, source: str = ""
                        ) -> Recording:
        """A recording from a kineticstoolkit ``TimeSeries`` of points ((frames, 4) or
        (frames, 3) arrays; ``labels``: which data keys, default all), each converted to mm
        from its data_info 'Unit' (default m, kineticstoolkit's).  The rate is from the time
        vector, which must be evenly spaced."""
        from facemotion.io.base import unit_scale

        where = source or "TimeSeries"
        labels = list(ts.data) if labels is None else [str(x) for x in labels]
        t = np.asarray(ts.time, dtype=float)
        rate = _even_rate(t, where)
        cols = []
        for label in labels:
            if label not in ts.data:
                raise InputError(f"{where}: no data {label!r}")
            arr = np.asarray(ts.data[label], dtype=float)
            if arr.ndim != 2 or arr.shape[1] not in (3, 4) or arr.shape[0] != t.size:
                raise InputError(f"{where}: data {label!r} has shape {arr.shape}; expected "
                                 f"({t.size}, 4) or ({t.size}, 3) points")
            unit = ts.info.get(label, {}).get("Unit", "m")
            cols.append(arr[:, :3] * unit_scale(str(unit), f"{where}: {label} unit"))
        return cls(labels, np.stack(cols, axis=1), rate, source)

    def select(self, labels: list[str]) -> Recording:
        """A new recording with only these markers, in this order."""
        idx = [self.index(label) for label in labels]
        # np.take copies (no memory shared with this recording) in C order, many times faster
        # than points[:, idx, :], whose result has the marker axis outermost in memory
        return Recording(list(labels), np.take(self.points, idx, axis=1), self.rate,
                         self.source, np.take(self.filled, idx, axis=1), self.units,
                         self.units_source)


def _even_rate(t: np.ndarray, where: str) -> float:
    """The frame rate of an evenly spaced time vector (s)."""
    if t.size < 2:
        raise InputError(f"{where}: fewer than 2 frames; the frame rate is undetermined")
    step = np.diff(t)
    if not np.allclose(step, step[0], rtol=1e-6, atol=0) or step[0] <= 0:
        raise InputError(f"{where}: time is not evenly spaced (steps {step.min():g} to "
                         f"{step.max():g} s); resample first")
    return float(1.0 / step.mean())


def _rate_of(da, where: str) -> float:
    rate = da.attrs.get("rate")
    if rate is not None:
        return float(rate)
    if "time" not in da.coords:
        raise InputError(f"{where}: neither a 'rate' attr nor a time coordinate")
    return _even_rate(np.asarray(da.coords["time"].values, dtype=float), where)
