"""C3D files read in blocks of frames with numpy, the points as :func:`facemotion.io.c3d.read_c3d`
gives them (ezc3d's reading), memory holding one block, never the take.

:func:`open_c3d_blocks` checks the file's size against its header (:func:`check_c3d_size`),
reads the parameter section (labels, rate, units, POINT:SCALE and the lists of points that are
not markers), and :meth:`C3DBlocks.blocks` then reads the data section in blocks. Per point and
frame a C3D file holds four words (C3D User Guide, "3D point data"):

* float storage (POINT:SCALE < 0): X, Y, Z as 4-byte floats, then a float: negative for
  an invalid sample, else an integer with the residual in its high byte and the cameras
  that saw the point in its low byte (as ezc3d reads it);
* integer storage (POINT:SCALE > 0): X, Y, Z as 16-bit integers times POINT:SCALE, then the
  camera mask byte and the residual byte (signed);

followed by the frame's analog samples. As in ``read_c3d``: the coordinates at the 32-bit
precision C3D stores, a sample missing (NaN) where its residual is negative, a coordinate not
finite, or all three are exactly 0 with a residual that is not positive. Only files written
for Intel processors (little-endian IEEE floats) are read in blocks; others are refused in one
line (the caller reads them whole, through ezc3d).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.io.base import check_readable
from facemotion.io.c3d import (
    C3DLayout,
    _header_disagreement,
    _marker_points,
    c3d_parameters,
    check_c3d_size,
    point_units,
)


@dataclass
class C3DBlocks:
    """An Intel C3D file's header and parameters, and its points in blocks (:meth:`blocks`)."""

    path: Path
    layout: C3DLayout
    rate: float
    labels: list[str]
    kept: np.ndarray           # indices of the points that are markers
    point_scale: float         # POINT:SCALE (< 0: float storage)
    scale: float               # unit scale to mm
    units: str
    units_source: str

    @property
    def n_frames(self) -> int:
        return self.layout.frames

    def blocks(self, block_bytes: int = 32 * 2**20) -> Iterator[tuple[int, np.ndarray]]:
        """(index of the block's first frame, its points (frames, markers, 3) in mm)."""
        lay = self.layout
        floats = lay.float_storage
        words = 4 * lay.points + lay.analog_per_frame
        dtype = np.dtype("<f4" if floats else "<i2")
        step = max(1, block_bytes // (words * dtype.itemsize))
        with open(self.path, "rb") as fh:
            fh.seek(lay.data_start)
            for a in range(0, lay.frames, step):
                b = min(lay.frames, a + step)
                raw = np.fromfile(fh, dtype=dtype, count=(b - a) * words)
                if raw.size != (b - a) * words:  # the size check makes this unreachable
                    raise InputError(f"{self.path}: C3D data section ends at frame {a}")
                yield a, self._points(raw.reshape(b - a, words)[:, :4 * lay.points])

    def _points(self, words: np.ndarray) -> np.ndarray:
        """(frames, markers, 3) mm from one block's point words (frames, 4 x points)."""
        F = len(words)
        w = words.reshape(F, self.layout.points, 4)[:, self.kept]
        if self.layout.float_storage:
            xyz = w[..., :3].astype(np.float64)
            # the 4th word, a float: negative for an invalid sample; else its integer part
            # holds the residual in the high byte (times |POINT:SCALE|), the cameras below
            f = w[..., 3].astype(np.float64)
            whole = np.trunc(np.where(np.isfinite(f) & (f >= 0), f, 0.0)).astype(np.int64)
            residual = np.where(f < 0, -1.0, (whole >> 8) & 0xFF)
        else:  # int16 x POINT:SCALE in double, kept at float32 as ezc3d's reading is
            xyz = (w[..., :3] * float(self.point_scale)).astype(np.float32).astype(np.float64)
            residual = w[..., 3:].view(np.int8)[..., 1].astype(np.float64)
        ok = np.isfinite(xyz[..., 0]) & np.isfinite(xyz[..., 1]) & np.isfinite(xyz[..., 2])
        invalid = (residual < 0) | ~ok
        invalid |= (xyz[..., 0] == 0) & (xyz[..., 1] == 0) & (xyz[..., 2] == 0) & ~(residual > 0)
        xyz *= self.scale
        xyz[invalid] = np.nan
        return xyz


def open_c3d_blocks(path, units: str | None = None) -> C3DBlocks:
    """An Intel C3D file's header and parameters (the checks and choices of
    :func:`~facemotion.io.c3d.read_c3d`), ready to give its points in blocks."""
    p = check_readable(path)
    layout = check_c3d_size(p)
    if layout.processor != "Intel":
        raise InputError(f"{p}: C3D written for a {layout.processor} processor; the block "
                         "reader reads Intel files only (read it whole)")
    damaged = _header_disagreement(p, layout)
    if damaged:
        logging.getLogger("facemotion").warning("%s: %s", p, damaged)
    point = c3d_parameters(p, layout).get("POINT", {})
    labels, kept = _marker_points(p, layout, point)
    rate_v = point.get("RATE", {}).get("value", [])
    with open(p, "rb") as fh:
        head = fh.read(512)
    rate = float(rate_v[0]) if rate_v else float(struct.unpack("<f", head[20:24])[0])
    scale_v = point.get("SCALE", {}).get("value", [])
    point_scale = float(scale_v[0]) if scale_v else float(struct.unpack("<f", head[12:16])[0])
    u = [str(x).strip() for x in point.get("UNITS", {}).get("value", [])]
    used, source, scale = point_units(u, units, p)
    return C3DBlocks(p, layout, rate, labels, kept, point_scale, scale, used, source)
