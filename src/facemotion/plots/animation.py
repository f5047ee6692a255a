"""Animation of the face driven by k main markers beside the measured face (paper Fig. 8).

The face surface is interpolated from the marker positions: every point of a grid over the
neutral (x, y) extent of the markers is carried to 3-D by piecewise-cubic (Clough-Tocher)
interpolation of the markers' current positions, neutral + displacement, over their neutral
(x, y) positions. Outside the markers' convex hull the surface is NaN (not drawn).

Frames are rendered off-screen at a fixed size, view and axis limits, so the same data give the
same pixels. matplotlib draws the static parts once (the two 3-D axes' panes, ticks, labels and
titles, the colour bar) on an Agg canvas, kept as the background. Each frame restores that
background and draws the moving parts without matplotlib's artists: the surface's quads are
projected with each panel's own projection (``ax.M``, ``proj3d.proj_transform``, then
``ax.transData`` to pixels), depth-sorted as mplot3d's ``Poly3DCollection`` sorts them (mean
projected depth of the four corners, farthest first) and painted by a numpy rasteriser that
fills, as Agg's aliased fill does, every pixel a quad overlaps, nearer quads over farther ones
(:func:`_fill_quads`); the marker dots are stamped by Agg's ``draw_markers`` in the marker
lines' own style (secondary, then main markers on top). The same frame drawn by matplotlib's
artists (``FaceAnimation.frame_reference``, as the still is drawn) differs in about 0.02 % of
the pixels, where a quad covers less than 1/256 of a pixel (tested); drawing it so takes about
twice the CPU. Each frame's caption is stamped onto the frame with Pillow in matplotlib's own
font (DejaVu Sans): matplotlib lays out and rasterises a changing title glyph by glyph, about
10 ms a frame. ``write_animation`` writes a GIF (Pillow) or an MP4 (libx264 through
imageio-ffmpeg) atomically; both are byte-identical on rerun (tested).

3-D axes: the head's (x, y, z) are drawn as matplotlib's (x, -z, y), a proper rotation, so the
vertical is y (up) and the default camera looks at the face from the front (azimuth -90):
the talker's right is on the viewer's left.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.path import Path as MplPath
from matplotlib.ticker import FuncFormatter, MaxNLocator
from matplotlib.transforms import IdentityTransform
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.interpolate import CloughTocher2DInterpolator
from scipy.spatial import Delaunay

from facemotion.errors import InputError
from facemotion.io.atomic import atomic_path
from facemotion.plots.facemap import (
    MAIN_COLOUR,
    MARKER_COLOUR,
    as_neutral,
    face_grid,
    interpolate_field,
    label_index,
)

if TYPE_CHECKING:
    from facemotion.ingest.displacements import Displacements

SURFACE_CMAP = "YlOrBr"  # colour-blind-safe sequential map for |displacement|, light at 0
FIGSIZE = (8.0, 4.6)  # inches; at DPI 100 -> 800 x 460 pixels (even, as libx264 needs)
DPI = 100
VIEW = (14.0, -72.0)  # elevation, azimuth (degrees): front, slightly above and to the left
FORMATS = ("gif", "mp4")
# Lambert shading: light from the front, above and from the talker's right (head axes).
LIGHT = np.array([-0.4, 0.5, 1.0]) / np.linalg.norm([-0.4, 0.5, 1.0])
AMBIENT = 0.45


def face_surface(neutral, displacement, grid_n: int = 30
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Face surface (X, Y, Z), each (grid_n, grid_n) mm, from marker positions.

    Grid over the (x, y) extent of the neutral markers; each grid point's 3-D position is the
    cubic (griddata 'cubic', Clough-Tocher) interpolation of neutral + displacement over the
    neutral (x, y) positions; NaN outside the markers' convex hull.
    """
    neutral = np.asarray(neutral, dtype=float)
    displacement = np.asarray(displacement, dtype=float)
    if neutral.ndim != 2 or neutral.shape[1] != 3 or displacement.shape != neutral.shape:
        raise InputError(f"face_surface: neutral {neutral.shape} and displacement "
                         f"{displacement.shape} must both be (markers, 3)")
    _, _, P = interpolate_field(neutral[:, :2], neutral + displacement, grid_n)
    return P[..., 0], P[..., 1], P[..., 2]


class _SurfaceInterpolator:
    """face_surface as one fixed linear map from marker values to grid values.

    The Clough-Tocher interpolant on a fixed triangulation is linear in the values (its
    gradient estimate solves a linear system, iterated to a relative tolerance of 1e-6), so
    interpolating the n unit vectors once gives weights W (grid, grid, n) and every frame is
    W @ values: the same surface as face_surface (to its own 1e-6 relative tolerance), at a
    matrix product a frame.
    """

    def __init__(self, neutral: np.ndarray, grid_n: int) -> None:
        xy = neutral[:, :2]
        self.gx, self.gy = face_grid(xy, grid_n)
        n = len(neutral)
        # tight tolerance: the unit vectors' gradients converge to well below a micrometre
        f = CloughTocher2DInterpolator(Delaunay(xy), np.eye(n), fill_value=np.nan, tol=1e-10,
                                       maxiter=5000)
        self.W = f(self.gx, self.gy)  # (grid_n, grid_n, n), NaN outside the hull
        self.neutral = neutral

    def __call__(self, displacement: np.ndarray) -> np.ndarray:
        """(grid_n, grid_n, 4): X, Y, Z and the interpolated |displacement|."""
        values = np.concatenate([self.neutral + displacement, displacement], axis=1)
        v = self.W @ values
        return np.concatenate([v[..., :3], np.linalg.norm(v[..., 3:], axis=-1)[..., None]],
                              axis=-1)


def _check_motion(neutral, measured, model, labels, main_labels):
    neutral, labels = as_neutral(neutral, labels)
    measured = np.asarray(measured, dtype=float)
    model = np.asarray(model, dtype=float)
    n = len(labels)
    if measured.ndim == 2:
        measured, model = measured[None], np.asarray(model, dtype=float)[None]
    if measured.ndim != 3 or measured.shape[1:] != (n, 3) or model.shape != measured.shape:
        raise InputError(f"animation: measured {measured.shape} and model {model.shape} "
                         f"displacements must both be (frames, {n} markers, 3)")
    if not (np.isfinite(measured).all() and np.isfinite(model).all()):
        raise InputError("animation: displacements contain NaN or infinite values "
                         "(fill gaps before animating)")
    main_idx = label_index(labels, [str(m) for m in main_labels], "main marker")
    return neutral, measured, model, labels, main_idx


# A quad's corners 0-3 (and 4: where its edges cross, if they do) as two triangles: a simple
# quad cut along its diagonal 0-2 or 1-3 (whichever is inside it), a bow-tie as its two lobes
# (both filled, as Agg's nonzero rule fills them).
_CUTS = np.array([[0, 1, 2, 0, 2, 3],   # diagonal 0-2
                  [0, 1, 3, 1, 2, 3],   # diagonal 1-3
                  [4, 1, 2, 4, 3, 0],   # edges 0-1 and 2-3 cross (at corner 4)
                  [4, 2, 3, 4, 0, 1]])  # edges 1-2 and 3-0 cross


def _quad_triangles(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners (N, 4) -> the quads' triangles' corners (2N, 3), quad i's as rows 2i, 2i + 1."""
    # t[:, k]: twice the signed area of the triangle of corners k, k + 1, k + 2 (mod 4); every
    # orientation test below is one of them
    x1, y1 = x[:, [1, 2, 3, 0]] - x, y[:, [1, 2, 3, 0]] - y
    x2, y2 = x[:, [2, 3, 0, 1]] - x, y[:, [2, 3, 0, 1]] - y
    t = x1 * y2 - y1 * x2
    t0, t1, t2, t3 = t.T
    bow_a = (t0 * t3 < 0) & (t1 * t2 < 0)  # edge 0-1 separates 2 and 3, edge 2-3 0 and 1
    bow_b = (t0 * t1 < 0) & (t2 * t3 < 0)  # edge 1-2 separates 3 and 0, edge 3-0 1 and 2
    with np.errstate(divide="ignore", invalid="ignore"):  # (used only where the edges cross)
        # where they cross: on edge 2-3 at t0 / (t0 - t3), on edge 3-0 at t1 / (t1 - t0)
        fa, fb = t0 / (t0 - t3), t1 / (t1 - t0)
        cx = np.where(bow_a, x[:, 2] + fa * (x[:, 3] - x[:, 2]), x[:, 3] + fb * (x[:, 0] - x[:, 3]))
        cy = np.where(bow_a, y[:, 2] + fa * (y[:, 3] - y[:, 2]), y[:, 3] + fb * (y[:, 0] - y[:, 3]))
    # a simple quad's diagonal 0-2 is inside it if corners 1 and 3 are on either side of it
    cut = (t0 * t2 <= 0).astype(np.intp)
    cut[bow_b] = 3
    cut[bow_a] = 2
    n = len(x)
    corner = _CUTS[cut] + 5 * np.arange(n)[:, None]
    return (np.column_stack([x, cx]).ravel()[corner].reshape(2 * n, 3),
            np.column_stack([y, cy]).ravel()[corner].reshape(2 * n, 3))


def _fill_quads(region: np.ndarray, quads: np.ndarray, colours: np.ndarray) -> None:
    """Paint quads, in order (later ones on top), onto ``region`` (h, w, 4) uint8 RGBA without
    antialiasing, as Agg fills an aliased path: every pixel the quad overlaps with positive area.

    quads (N, 4, 2): corners in the region's pixel coordinates (x right, y down; pixel (r, c)
    is the unit square [c, c + 1] x [r, r + 1]); colours (N, 3) uint8, drawn opaque. Pixels
    outside the region are clipped. Each quad is cut into two triangles whose union is the
    area Agg fills (:func:`_quad_triangles`), so the pixels they touch are the pixels it
    touches. A triangle's pixels are, row by row, the columns its part within the row's strip
    spans: x is linear along each edge, so that span's ends lie on the strip's two lines
    (clamped to the triangle's height) or at the middle corner.
    """
    h, w = region.shape[:2]
    n = len(quads)
    # single precision from here: at a few hundred pixels, steps of 3e-5 px
    tx, ty = _quad_triangles(quads[..., 0].astype(np.float32), quads[..., 1].astype(np.float32))
    area2 = ((tx[:, 1] - tx[:, 0]) * (ty[:, 2] - ty[:, 0])
             - (ty[:, 1] - ty[:, 0]) * (tx[:, 2] - tx[:, 0]))
    keep = np.flatnonzero(np.abs(area2) > 1e-6)  # a triangle of zero area covers nothing
    (xa, xb, xc), (ya, yb, yc) = tx[keep].T, ty[keep].T
    rank = (keep >> 1).astype(np.int32)  # the quad each triangle belongs to

    def top_first(x0, y0, x1, y1):
        swap = y1 < y0
        return (np.where(swap, x1, x0), np.where(swap, y1, y0), np.where(swap, x0, x1),
                np.where(swap, y0, y1))

    # corners top to bottom: a, b, c (ya < yc, as the area is positive)
    xa, ya, xb, yb = top_first(xa, ya, xb, yb)
    xb, yb, xc, yc = top_first(xb, yb, xc, yc)
    xa, ya, xb, yb = top_first(xa, ya, xb, yb)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_ac = (xc - xa) / (yc - ya)
        # a horizontal edge's two ends are span ends anyway (corner a or b, and the long edge)
        s_ab = np.where(yb > ya, (xb - xa) / (yb - ya), np.float32(0))
        s_bc = np.where(yc > yb, (xc - xb) / (yc - yb), np.float32(0))
    # rows whose strip [r, r + 1] meets the triangle with positive area, within the region
    r0 = np.clip(np.floor(ya), 0, h).astype(np.int32)
    rows = np.maximum(np.clip(np.ceil(yc), 0, h).astype(np.int32) - r0, 0)
    if not rows.any():
        return
    first = np.cumsum(rows, dtype=np.int32) - rows
    row = np.repeat(r0 - first, rows) + np.arange(first[-1] + rows[-1], dtype=np.int32)
    xa, xb, ya, yb, yc, s_ac, s_ab, s_bc, rank = (
        np.repeat(v, rows) for v in (xa, xb, ya, yb, yc, s_ac, s_ab, s_bc, rank))
    top = row.astype(np.float32)
    lo, hi = np.full(row.size, np.inf, np.float32), np.full(row.size, -np.inf, np.float32)
    for line in (top, top + 1):
        yl = np.clip(line, ya, yc)
        for xl in (xa + (yl - ya) * s_ac,
                   np.where(yl <= yb, xa + (yl - ya) * s_ab, xb + (yl - yb) * s_bc)):
            np.minimum(lo, xl, out=lo)
            np.maximum(hi, xl, out=hi)
    middle = (yb >= top) & (yb <= top + 1)
    np.minimum(lo, np.where(middle, xb, np.inf), out=lo)
    np.maximum(hi, np.where(middle, xb, -np.inf), out=hi)
    c0 = np.clip(np.floor(lo), 0, w).astype(np.int32)
    c1 = np.clip(np.ceil(hi), 0, w).astype(np.int32)
    span = np.where(hi > lo, np.maximum(c1 - c0, 0), 0)
    if not span.any():
        return
    # the painted box of the region, and each pixel's topmost (last drawn) quad in it
    b_r0, b_r1 = int(row.min()), int(row.max()) + 1
    b_c0, b_c1 = int(c0[span > 0].min()), int(c1[span > 0].max())
    bw = b_c1 - b_c0
    start = np.cumsum(span, dtype=np.int32) - span
    pix = (np.repeat((row - b_r0) * bw + (c0 - b_c0) - start, span)
           + np.arange(start[-1] + span[-1], dtype=np.int32))
    seen = np.full((b_r1 - b_r0) * bw, -1, dtype=np.int32)
    np.maximum.at(seen, pix, np.repeat(rank, span))  # painter's algorithm
    seen = seen.reshape(b_r1 - b_r0, bw)
    rgba = np.zeros((n + 1, 4), dtype=np.uint8)
    rgba[1:, :3] = colours
    rgba[1:, 3] = 255
    # one 32-bit word a pixel (the box is a strided view of the image's rows)
    np.copyto(region[b_r0:b_r1, b_c0:b_c1].view(np.uint32)[..., 0],
              rgba.view(np.uint32)[seen + 1, 0], where=seen >= 0)


class _Renderer:
    """One figure with two 3-D panels, reused for every frame (fixed size, view, limits).

    The static parts (panes, axes, titles, colour bar) are rendered once by matplotlib and kept
    as the background. Each frame (:meth:`rgb`) restores that background and draws the two
    surfaces itself: the quads' corners are projected with each panel's own projection
    (``ax.M``, then ``ax.transData`` to pixels), depth-sorted as ``Poly3DCollection`` sorts
    them (mean projected depth, farthest first) and filled without antialiasing by
    :func:`_fill_quads`; the markers are stamped by the Agg renderer's ``draw_markers`` with
    the marker lines' own style, and the caption with Pillow. :meth:`rgb_reference` draws the
    same frame with matplotlib's artists (as :meth:`still` does), for tests and benchmarks.
    """

    def __init__(self, neutral, labels, main_idx, grid_n, vmax, limits, view=VIEW,
                 figsize=FIGSIZE, dpi=DPI, axes_visible=True):
        self.neutral, self.labels, self.main_idx = neutral, labels, main_idx
        self.rest_idx = np.setdiff1d(np.arange(len(labels)), main_idx)
        self._surface_quads(neutral, grid_n)
        self.fig = Figure(figsize=figsize, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self.norm = Normalize(0.0, vmax)
        self.cmap = colormaps[SURFACE_CMAP]
        # the colormap's N colours, then its colour above the range (see _colour)
        self._table = np.vstack([self.cmap(np.arange(self.cmap.N)), self.cmap([np.inf])])
        k = len(main_idx)
        titles = ("measured", f"model from the k = {k} main markers (red)")
        self.axes, self.polys, self.dots, self.mains = [], [], [], []
        for p in range(2):
            self._add_panel(p, titles[p], view, limits, axes_visible)
        cax = self.fig.add_axes((0.91, 0.18, 0.015, 0.6))
        cb = self.fig.colorbar(ScalarMappable(norm=self.norm, cmap=self.cmap), cax=cax)
        cb.set_label("|displacement| (mm)", fontsize=8)
        cb.ax.tick_params(labelsize=7)
        self.suptitle = self.fig.suptitle("", fontsize=9.5, y=0.985, va="top")
        self._title_font = None  # Pillow's copy of the suptitle's font, loaded on first use
        self.dynamic = [*self.polys, *self.dots, *self.mains, self.suptitle]
        self._render_static()
        self._scenes = None  # the frame's geometry and colours, set by draw()
        self._artists_current = False

    def _surface_quads(self, neutral: np.ndarray, grid_n: int) -> None:
        """The surface's interpolator and the quads of its grid that are drawn, with their
        corners' rows among the grid points used and those points' weights."""
        self.surface = _SurfaceInterpolator(neutral, grid_n)
        # Quads of the grid with all four corners inside the markers' hull: fixed, because the
        # grid lives in neutral (x, y) coordinates.
        inside = np.isfinite(self.surface(np.zeros_like(neutral))[..., 0])
        q = inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:]
        self.quads = np.argwhere(q)
        # Each quad's corners (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1) as rows of the
        # grid points the quads use, and those points' interpolation weights.
        i, j = self.quads[:, 0], self.quads[:, 1]
        flat = np.stack([i * grid_n + j, (i + 1) * grid_n + j, (i + 1) * grid_n + j + 1,
                         i * grid_n + j + 1], axis=1)
        used, self._corner = np.unique(flat, return_inverse=True)
        self._corner = self._corner.reshape(flat.shape)
        self._weights = self.surface.W.reshape(grid_n * grid_n, -1)[used]

    def _add_panel(self, p: int, title: str, view, limits, axes_visible: bool) -> None:
        """Panel p (0 measured, 1 model): a 3-D axes with the fixed view and limits, its
        surface and its two marker lines (secondary, main)."""
        (xl, yl, zl) = limits
        # panels kept clear of the figure's edges so the axis labels are not cut off
        ax = self.fig.add_axes((0.01 + 0.44 * p, 0.03, 0.44, 0.86), projection="3d",
                               computed_zorder=False)
        ax.set_title(title, fontsize=10, pad=2)
        ax.view_init(elev=view[0], azim=view[1])
        ax.set_xlim(*xl)
        ax.set_ylim(-zl[1], -zl[0])
        ax.set_zlim(*yl)
        ax.set_box_aspect((xl[1] - xl[0], zl[1] - zl[0], yl[1] - yl[0]))
        if axes_visible:
            ax.set_xlabel("x (mm)", fontsize=7, labelpad=-6)
            ax.set_ylabel("z (mm)", fontsize=7, labelpad=-6)
            ax.set_zlabel("y (mm)", fontsize=7, labelpad=0)
            ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{-v + 0.0:g}"))
            ax.xaxis.set_major_locator(MaxNLocator(4))
            ax.zaxis.set_major_locator(MaxNLocator(4))
            # depth is seen nearly end-on: two ticks, or their labels collide
            ax.yaxis.set_major_locator(MaxNLocator(2))
            ax.tick_params(labelsize=6, pad=-3)
            ax.zaxis.set_tick_params(pad=2)  # clear of the tick marks: keep the minus signs
        else:
            ax.set_axis_off()
        poly = Poly3DCollection(np.zeros((len(self.quads), 4, 3)), linewidths=0,
                                antialiased=False, zorder=1)
        ax.add_collection3d(poly, autolim=False)
        (dots,) = ax.plot([], [], [], ls="none", marker="o", ms=1.8, color=MARKER_COLOUR,
                          mew=0, zorder=2)
        (mains,) = ax.plot([], [], [], ls="none", marker="o", ms=4.5, color=MAIN_COLOUR,
                           mec="white", mew=0.5, zorder=3)
        self.axes.append(ax)
        self.polys.append(poly)
        self.dots.append(dots)
        self.mains.append(mains)

    def _render_static(self) -> None:
        """Draw everything but the moving parts once, keep it as the background, and fix each
        panel's projection, data -> pixel map, clip box and marker styles."""
        for a in self.dynamic:
            a.set_visible(False)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        for a in self.dynamic:
            a.set_visible(True)
        renderer = self.canvas.get_renderer()
        self._proj = [(ax.M.copy(), ax.transData.get_affine().get_matrix().copy())
                      for ax in self.axes]
        self._clip = [self._pixel_clip(poly, renderer) for poly in self.polys]
        self._markers = [[self._marker_style(line, renderer)
                          for line in (self.dots[p], self.mains[p])] for p in range(2)]

    @staticmethod
    def _pixel_clip(artist, renderer) -> tuple[int, int, int, int]:
        """The artist's clip box as Agg applies it: rows r0:r1, columns c0:c1 of the image."""
        h, w = renderer.height, renderer.width
        x0, y0, x1, y1 = artist.get_clip_box().extents if artist.get_clip_on() else (0, 0, w, h)
        c0, c1 = max(math.floor(x0 + 0.5), 0), min(math.floor(x1 + 0.5), w)
        r0, r1 = max(math.floor(h - y1 + 0.5), 0), min(math.floor(h - y0 + 0.5), h)
        return r0, r1, c0, c1

    @staticmethod
    def _marker_style(line, renderer):
        """What ``Line2D.draw`` hands the renderer for the line's markers (no line drawn):
        the graphics context, marker path and its transform (size in points -> pixels), face
        colour."""
        from matplotlib.colors import to_rgba
        from matplotlib.markers import MarkerStyle

        gc = renderer.new_gc()
        if line.get_clip_on():
            gc.set_clip_rectangle(line.get_clip_box())
            gc.set_clip_path(line.get_clip_path())
        gc.set_linewidth(line.get_markeredgewidth())
        gc.set_antialiased(line.get_antialiased())
        gc.set_foreground(to_rgba(line.get_markeredgecolor(), line.get_alpha()), isRGBA=True)
        marker = MarkerStyle(line.get_marker(), line.get_fillstyle())
        size = renderer.points_to_pixels(line.get_markersize())
        snap = marker.get_snap_threshold()
        gc.set_snap(size >= snap if snap is not None else None)
        gc.set_joinstyle(marker.get_joinstyle())
        gc.set_capstyle(marker.get_capstyle())
        face = to_rgba(line.get_markerfacecolor(), line.get_alpha())
        return gc, marker.get_path(), marker.get_transform().scale(size), face

    def _scene(self, d: np.ndarray):
        """A panel's frame in matplotlib's coordinates (x, -z, y): the surface's grid points
        used by the quads, the quads' Lambert-shaded RGBA colours (N, 4), and the secondary
        and main markers' positions."""
        values = np.concatenate([self.neutral + d, d], axis=1)
        v = self._weights @ values  # the surface at the quads' corners (_SurfaceInterpolator)
        c = v[self._corner]  # (N, 4 corners, 6)
        # Lambert shading of each quad: normal from its diagonals (pointing forward, +z).
        n = np.cross(c[:, 3, :3] - c[:, 1, :3], c[:, 2, :3] - c[:, 0, :3])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        shade = AMBIENT + (1 - AMBIENT) * np.clip(n @ LIGHT, 0.0, 1.0)
        mag = np.sqrt(np.einsum("qck,qck->qc", c[..., 3:], c[..., 3:]))
        rgba = self._colour((mag[:, 0] + mag[:, 1] + mag[:, 2] + mag[:, 3]) / 4)
        rgba[:, :3] *= shade[:, None]
        grid = v[:, [0, 2, 1]]  # head (x, y, z) -> (x, -z, y)
        grid[:, 1] *= -1
        p = (self.neutral + d)[:, [0, 2, 1]]
        p[:, 1] *= -1
        return grid, rgba, p[self.rest_idx], p[self.main_idx]

    def _colour(self, mag: np.ndarray) -> np.ndarray:
        """``cmap(norm(mag))`` for mag >= 0 (RGBA (N, 4)), by the colormap's own table:
        Normalize's (mag - 0) / vmax, then Colormap's index floor(x N), 1 -> N - 1, above 1
        the 'over' colour."""
        x = mag / self.norm.vmax * self.cmap.N
        x[x == self.cmap.N] = self.cmap.N - 1
        return self._table[np.minimum(x, self.cmap.N).astype(int)]

    def draw(self, measured: np.ndarray, model: np.ndarray, title: str) -> None:
        """Set the frame: both panels' geometry and the caption (drawn by :meth:`rgb`, or by
        the artists after :meth:`sync_artists`)."""
        self.suptitle.set_text(title)
        self._scenes = [self._scene(measured), self._scene(model)]
        self._artists_current = False

    def sync_artists(self) -> None:
        """Hand the frame to matplotlib's artists (for a full draw: the still, the reference)."""
        if self._artists_current:
            return
        for p, (grid, rgba, rest, main) in enumerate(self._scenes):
            self.polys[p].set_verts(grid[self._corner])
            self.polys[p].set_facecolor(rgba)
            self.dots[p].set_data_3d(rest[:, 0], rest[:, 1], rest[:, 2])
            self.mains[p].set_data_3d(main[:, 0], main[:, 1], main[:, 2])
        self._artists_current = True

    def project(self, p: int, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (..., 3) in panel p's data coordinates -> display pixels x, y (origin at the
        bottom left, as matplotlib's) and projected depth, as the panel's artists project them
        (``proj3d.proj_transform`` with ``ax.M``, then ``ax.transData``)."""
        M, A = self._proj[p]
        shape = xyz.shape[:-1]
        xs, ys, zs = proj3d.proj_transform(xyz[..., 0].ravel(), xyz[..., 1].ravel(),
                                           xyz[..., 2].ravel(), M)
        px = A[0, 0] * xs + A[0, 1] * ys + A[0, 2]
        py = A[1, 0] * xs + A[1, 1] * ys + A[1, 2]
        return px.reshape(shape), py.reshape(shape), zs.reshape(shape)

    def rgb(self) -> np.ndarray:
        """The frame: static background, then per panel the surface (depth-sorted quads filled
        by :func:`_fill_quads`), the secondary and the main markers; the caption is stamped
        with Pillow (:meth:`_stamp_title`)."""
        self.canvas.restore_region(self.background)
        renderer = self.canvas.get_renderer()
        buf = np.asarray(renderer.buffer_rgba())
        height = buf.shape[0]
        for p, (grid, rgba, rest, main) in enumerate(self._scenes):
            px, py, pz = self.project(p, np.concatenate([grid, rest, main]))
            row = height - py  # image rows run down
            r0, r1, c0, c1 = self._clip[p]
            # Poly3DCollection's order: mean projected depth of the 4 corners, farthest first
            order = np.argsort(np.average(pz[self._corner], axis=-1))[::-1]
            corner = self._corner[order]
            quads = np.stack([px[corner] - c0, row[corner] - r0], axis=-1)
            colours = np.floor(rgba[order, :3] * 255.0 + 0.5).astype(np.uint8)  # as Agg rounds
            _fill_quads(buf[r0:r1, c0:c1], quads, colours)
            # the markers, secondary then main, at their display positions
            at = np.cumsum([len(grid), len(rest), len(main)])
            for (gc, path, trans, face), pts in zip(
                    self._markers[p], (slice(at[0], at[1]), slice(at[1], at[2])), strict=True):
                if pts.stop > pts.start:
                    xy = np.column_stack([px[pts], py[pts]])
                    renderer.draw_markers(gc, path, trans, MplPath(xy), IdentityTransform(), face)
        return self._finish(buf)

    def rgb_reference(self) -> np.ndarray:
        """The same frame drawn by matplotlib's artists (blitted onto the same background)."""
        self.sync_artists()
        self.canvas.restore_region(self.background)
        for p, ax in enumerate(self.axes):
            self.polys[p].do_3d_projection()
            for artist in (self.polys[p], self.dots[p], self.mains[p]):
                ax.draw_artist(artist)
        return self._finish(np.asarray(self.canvas.buffer_rgba()))

    def _finish(self, rgba: np.ndarray) -> np.ndarray:
        rgb = np.empty(rgba.shape[:2] + (3,), dtype=np.uint8)
        for c in range(3):  # channel by channel: ~7x faster than rgba[..., :3].copy()
            rgb[..., c] = rgba[..., c]
        self._stamp_title(rgb, self.suptitle.get_text())
        return rgb

    def _stamp_title(self, rgb: np.ndarray, text: str) -> None:
        """Draw ``text`` centred at the suptitle's place (its top at the suptitle's y) in the
        suptitle's font, size and colour, onto the strip of ``rgb`` it covers."""
        if not text:
            return
        from PIL import Image, ImageDraw

        if self._title_font is None:
            from matplotlib import font_manager
            from PIL import ImageFont

            path = font_manager.findfont(self.suptitle.get_fontproperties())
            size_px = self.suptitle.get_fontsize() * self.fig.dpi / 72.0
            self._title_font = ImageFont.truetype(path, size_px)
        h, w = rgb.shape[:2]
        top = int(round((1.0 - self.suptitle.get_position()[1]) * h))
        strip_h = min(h, top + int(np.ceil(2 * self.fig.dpi * self.suptitle.get_fontsize()
                                           / 72.0)))
        strip = Image.fromarray(rgb[:strip_h])
        colour = tuple(int(round(255 * c)) for c in to_rgb(self.suptitle.get_color()))
        ImageDraw.Draw(strip).text((w / 2.0, top), text, font=self._title_font, fill=colour,
                                   anchor="ma")
        rgb[:strip_h] = np.asarray(strip)


def _limits(neutral: np.ndarray, *motions: np.ndarray, pad: float = 2.0):
    pos = np.concatenate([neutral[None] + m for m in motions], axis=0).reshape(-1, 3)
    pos = np.concatenate([pos, neutral])
    lo, hi = pos.min(axis=0) - pad, pos.max(axis=0) + pad
    return tuple((float(lo[a]), float(hi[a])) for a in range(3))


def _vmax(*motions: np.ndarray) -> float:
    mags = np.concatenate([np.linalg.norm(m, axis=-1).ravel() for m in motions])
    v = float(np.percentile(mags, 99.0)) if mags.size else 1.0
    return max(v, 0.5)


class FaceAnimation:
    """Frames and stills of one animation (measured face beside the model), all drawn by one
    renderer with the colour scale and axis limits of the whole motion.

    neutral (n, 3) mm; measured and model (T, n, 3) displacements from neutral. The figure is
    built and its static parts rendered once; each frame paints the surfaces, markers and
    caption onto that background (see the module's docstring), so frames cost a fraction of a
    full draw; a still of any frame is the same figure drawn by its artists.
    """

    def __init__(self, neutral, measured, model, labels: Sequence[str],
                 main_labels: Sequence[str], grid_n: int = 30, axes_visible: bool = True):
        neutral, measured, model, labels, main_idx = _check_motion(neutral, measured, model,
                                                                   labels, main_labels)
        self.measured, self.model = measured, model
        self._r = _Renderer(neutral, labels, main_idx, grid_n, _vmax(measured, model),
                            _limits(neutral, measured, model), axes_visible=axes_visible)

    def __len__(self) -> int:
        return self.measured.shape[0]

    def frame(self, i: int, caption: str) -> np.ndarray:
        """Frame i as an (H, W, 3) uint8 RGB array."""
        self._r.draw(self.measured[i], self.model[i], caption)
        return self._r.rgb()

    def frame_reference(self, i: int, caption: str) -> np.ndarray:
        """Frame i drawn by matplotlib's artists instead (Poly3DCollection, Line3D), as the
        still is: the reference :meth:`frame` is tested and benchmarked against; slower."""
        self._r.draw(self.measured[i], self.model[i], caption)
        return self._r.rgb_reference()

    def frames(self, captions: Sequence[str]) -> Iterator[np.ndarray]:
        """All frames in order (one in memory at a time), one caption each."""
        if len(captions) != len(self):
            raise InputError(f"animation: {len(captions)} captions for {len(self)} frames")
        for i, c in enumerate(captions):
            yield self.frame(i, c)

    def still(self, i: int, caption: str) -> Figure:
        """Frame i as a Figure (for a PNG/PDF still); draw no frames after taking it."""
        self._r.draw(self.measured[i], self.model[i], caption)
        self._r.sync_artists()
        return self._r.fig


def _time_captions(n: int, fps: float, t0: float, title: str) -> list[str]:
    if not fps > 0:
        raise InputError(f"animation: fps must be positive, got {fps}")
    prefix = f"{title}  " if title else ""
    return [f"{prefix}t = {t0 + i / fps:6.3f} s" for i in range(n)]


def iter_frames(neutral, measured, model, labels: Sequence[str], main_labels: Sequence[str],
                fps: float, grid_n: int = 30, t0: float = 0.0, title: str = "",
                axes_visible: bool = True, captions: Sequence[str] | None = None
                ) -> Iterator[np.ndarray]:
    """Generator form of :func:`render_frames` (one frame in memory at a time)."""
    anim = FaceAnimation(neutral, measured, model, labels, main_labels, grid_n=grid_n,
                         axes_visible=axes_visible)
    if captions is None:
        captions = _time_captions(len(anim), fps, t0, title)
    yield from anim.frames(captions)


def render_frames(neutral, measured, model, labels: Sequence[str], main_labels: Sequence[str],
                  fps: float, grid_n: int = 30, t0: float = 0.0, title: str = "",
                  axes_visible: bool = True, captions: Sequence[str] | None = None
                  ) -> list[np.ndarray]:
    """Render frames of the measured face beside the face predicted from the main markers.

    neutral (n, 3) mm; measured and model (T, n, 3) displacements from neutral (already
    subsampled to the output rate ``fps``, which only sets the time stamps). Main markers are
    drawn in red. Colour is |displacement| (mm) on one fixed scale (99th percentile of both);
    axis limits and view are fixed for all frames. Each frame's caption is ``captions[i]``
    (default: ``title`` and the time). Returns T RGB uint8 arrays (H, W, 3).
    """
    return list(iter_frames(neutral, measured, model, labels, main_labels, fps, grid_n=grid_n,
                            t0=t0, title=title, axes_visible=axes_visible, captions=captions))


def still_frame(neutral, measured, model, labels: Sequence[str], main_labels: Sequence[str],
                grid_n: int = 30, title: str = "") -> Figure:
    """One frame (measured and model displacements (n, 3)) as a Figure, for the PNG still."""
    anim = FaceAnimation(neutral, np.asarray(measured, dtype=float)[None],
                         np.asarray(model, dtype=float)[None], labels, main_labels,
                         grid_n=grid_n)
    return anim.still(0, title or "Measured face and face predicted from the main markers "
                      "(red)")


def frame_indices(n_frames: int, rate: float, fps: float) -> tuple[np.ndarray, float]:
    """Subsample a recording at ``rate`` Hz to at most ``fps``: frame indices and the exact
    output rate (rate / step, step the smallest whole number of frames that keeps the output
    rate at or below ``fps``)."""
    if not (rate > 0 and fps > 0):
        raise InputError(f"animation: rate ({rate}) and fps ({fps}) must be positive")
    step = max(1, math.ceil(rate / fps - 1e-9))
    return np.arange(0, n_frames, step), rate / step


@dataclass
class HeldoutClip:
    """Held-out sentences to animate: measured and model displacements (T, n, 3) of the frames
    kept at the output rate ``fps``, and each frame's caption."""

    measured: np.ndarray
    model: np.ndarray
    captions: list[str]
    fps: float

    @property
    def largest_motion(self) -> int:
        """The frame whose markers are displaced most (sum of |x|, |y|, |z| over markers):
        the still."""
        return int(np.argmax(np.abs(self.measured).sum(axis=(1, 2))))


def heldout_clip(part: Displacements, predicted: np.ndarray, fps: float, label: str
                 ) -> HeldoutClip:
    """The held-out sentences ``part`` and the model's prediction of them (rows as in A),
    subsampled to at most ``fps`` (:func:`frame_indices`); each frame's caption names the
    dataset ``label``, its sentence, its frame there and the time in the sentence."""
    n = len(part.labels)
    measured = part.A.reshape(-1, 3, n).transpose(0, 2, 1)
    model = predicted.reshape(-1, 3, n).transpose(0, 2, 1)
    idx, out_fps = frame_indices(measured.shape[0], part.rate, fps)
    sent = part.row_sentence[::3][idx]
    frame = part.row_frame[::3][idx]
    n_in = {s: int(np.sum(part.row_sentence[::3] == s)) for s in set(sent.tolist())}
    captions = [f"{label}: held-out sentence {part.sentences[s]}, frame {f + 1} of "
                f"{n_in[s]} (t = {f / part.rate:.2f} s)" for s, f in zip(sent, frame, strict=True)]
    return HeldoutClip(measured[idx], model[idx], captions, out_fps)


def _as_frames(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    shape = None
    for i, f in enumerate(frames):
        f = np.asarray(f)
        if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
            raise InputError(f"animation frame {i}: expected (H, W, 3) uint8 RGB, got "
                             f"{f.shape} {f.dtype}")
        if shape is None:
            shape = f.shape
        elif f.shape != shape:
            raise InputError(f"animation frame {i}: size {f.shape} differs from {shape}")
        yield f


def _gif_durations_ms(n: int, fps: float) -> list[int]:
    """Per-frame GIF delays (GIF counts in 10 ms units): whole centiseconds whose running sum
    tracks i / fps, so a 30 fps animation alternates 30 and 40 ms and keeps time."""
    t = np.round(np.arange(n + 1) * 100.0 / fps).astype(int)
    return (np.maximum(np.diff(t), 1) * 10).tolist()


def _write_gif(path: str, frames: list[np.ndarray], fps: float) -> None:
    from PIL import Image

    images = [Image.fromarray(f).quantize(colors=255, method=Image.Quantize.FASTOCTREE,
                                          dither=Image.Dither.NONE) for f in frames]
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:],
                   duration=_gif_durations_ms(len(images), fps), loop=0, optimize=False,
                   disposal=1)


def _write_mp4(path: str, frames: Iterable[np.ndarray], fps: float, crf: int) -> None:
    import imageio.v2 as imageio

    params = ["-fflags", "+bitexact", "-flags:v", "+bitexact", "-map_metadata", "-1",
              "-threads", "1", "-crf", str(int(crf)), "-preset", "veryfast", "-tune", "animation"]
    writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=float(fps),
                                codec="libx264", pixelformat="yuv420p", quality=None,
                                macro_block_size=1, ffmpeg_log_level="error",
                                ffmpeg_params=params)
    try:
        for f in frames:
            h, w = f.shape[:2]
            if h % 2 or w % 2:  # yuv420p needs even sizes: repeat the last row / column
                f = np.pad(f, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
            writer.append_data(f)
    finally:
        writer.close()


def write_animation(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float,
                    crf: int = 20) -> Path:
    """Write frames (RGB uint8, all the same size) as a GIF or MP4, chosen by the suffix.

    GIF: Pillow, one fast-octree palette per frame, no dithering, looping; delays in whole
    centiseconds tracking 1/fps. Pillow merges a frame identical to the one before into it
    (adding its delay), so a GIF can hold fewer frames than given while keeping the timing.
    MP4: H.264 (libx264, yuv420p, CRF ``crf``, preset veryfast: half the encoding CPU of
    'medium' at about the same file size on the study's animations; 'superfast' and
    'ultrafast' take 25 % and 47 % less CPU than veryfast but make the files 2.0 and 2.5 times
    larger: on the default study's 529 frames 11.3, 8.4 and 6.0 ms a frame, 2.1, 4.1 and 5.2
    MB) with bit-exact flags, one thread and no metadata, so a rerun is byte-identical; odd
    frame sizes are padded by one pixel.
    The file is written beside ``path`` under a temporary name and renamed into place.
    """
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise InputError(f"{path}: animation format must be one of {FORMATS} (by suffix)")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"{path}: fps must be positive, got {fps}")
    frames = _as_frames(frames)
    first = next(frames, None)
    if first is None:
        raise InputError(f"{path}: no frames to write")
    frames = itertools.chain([first], frames)  # streamed to the MP4 encoder
    with atomic_path(path, suffix=f".{fmt}") as tmp:
        if fmt == "gif":
            _write_gif(str(tmp), list(frames), fps)
        else:
            _write_mp4(str(tmp), frames, fps, crf)
    return path


def animation_page(path: str | os.PathLike, title: str, caption: str = "") -> bytes:
    """A small self-contained HTML page that plays the animation at ``path`` (MP4 in a looping
    <video>, GIF in an <img>), the file embedded as a data URI, for the Snakemake report
    (which shows HTML inline but offers other files only as downloads)."""
    import base64
    import html

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise InputError(f"{path}: animation format must be one of {FORMATS} (by suffix)")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    if fmt == "mp4":
        media = (f'<video controls loop autoplay muted playsinline style="max-width:100%" '
                 f'src="data:video/mp4;base64,{data}"></video>')
    else:
        media = f'<img style="max-width:100%" alt="animation" src="data:image/gif;base64,{data}">'
    text = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{html.escape(title)}</title></head>\n"
            f'<body style="margin:0;font-family:sans-serif">\n<p style="margin:4px 8px">'
            f"{html.escape(title)}</p>\n{media}\n"
            + (f'<p style="margin:4px 8px;font-size:90%">{html.escape(caption)}</p>\n'
               if caption else "")
            + "</body></html>\n")
    return text.encode("utf-8")
