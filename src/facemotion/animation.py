"""Animation of the face driven by k main markers beside the measured face (paper Fig. 8).

The face surface is interpolated from the marker positions: every point of a grid over the
neutral (x, y) extent of the markers is carried to 3-D by piecewise-cubic (Clough-Tocher)
interpolation of the markers' current positions, neutral + displacement, over their neutral
(x, y) positions. Outside the markers' convex hull the surface is NaN (not drawn).

Frames are rendered off-screen with the Agg canvas at a fixed size, view and axis limits, so
the same data give the same pixels. Each frame's caption is stamped onto the frame with Pillow in
matplotlib's own font (DejaVu Sans): matplotlib lays out and rasterises a changing title glyph
by glyph, about 10 ms a frame, more than the two surfaces together. ``write_animation`` writes
a GIF (Pillow) or an MP4 (libx264 through imageio-ffmpeg) atomically; both are byte-identical
on rerun (tested).

3-D axes: the head's (x, y, z) are drawn as matplotlib's (x, -z, y), a proper rotation, so the
vertical is y (up) and the default camera looks at the face from the front (azimuth -90):
the talker's right is on the viewer's left.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.interpolate import CloughTocher2DInterpolator
from scipy.spatial import Delaunay

from facemotion.errors import InputError
from facemotion.plots.facemap import (
    MAIN_COLOUR,
    MARKER_COLOUR,
    as_neutral,
    face_grid,
    interpolate_field,
    label_index,
)
from facemotion.provenance import atomic_path

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


class _Renderer:
    """One figure with two 3-D panels, reused for every frame (fixed size, view, limits).

    The static parts (panes, axes, titles, colour bar) are rendered once; each frame restores
    that background and draws only the two surfaces, the markers and the time stamp (blitting),
    which is several times faster than a full redraw and gives the same pixels every run.
    """

    def __init__(self, neutral, labels, main_idx, grid_n, vmax, limits, view=VIEW,
                 figsize=FIGSIZE, dpi=DPI, axes_visible=True):
        self.neutral, self.labels, self.main_idx = neutral, labels, main_idx
        self.rest_idx = np.setdiff1d(np.arange(len(labels)), main_idx)
        self.surface = _SurfaceInterpolator(neutral, grid_n)
        # Quads of the grid with all four corners inside the markers' hull: fixed, because the
        # grid lives in neutral (x, y) coordinates.
        inside = np.isfinite(self.surface(np.zeros_like(neutral))[..., 0])
        q = inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:]
        self.quads = np.argwhere(q)
        self.fig = Figure(figsize=figsize, dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self.norm = Normalize(0.0, vmax)
        self.cmap = colormaps[SURFACE_CMAP]
        k = len(main_idx)
        titles = ("measured", f"model from the k = {k} main markers (red)")
        self.axes, self.polys, self.dots, self.mains = [], [], [], []
        (xl, yl, zl) = limits
        for p in range(2):
            # panels kept clear of the figure's edges so the axis labels are not cut off
            ax = self.fig.add_axes((0.01 + 0.44 * p, 0.03, 0.44, 0.86), projection="3d",
                                   computed_zorder=False)
            ax.set_title(titles[p], fontsize=10, pad=2)
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
        cax = self.fig.add_axes((0.91, 0.18, 0.015, 0.6))
        cb = self.fig.colorbar(ScalarMappable(norm=self.norm, cmap=self.cmap), cax=cax)
        cb.set_label("|displacement| (mm)", fontsize=8)
        cb.ax.tick_params(labelsize=7)
        self.suptitle = self.fig.suptitle("", fontsize=9.5, y=0.985, va="top")
        self._title_font = None  # Pillow's copy of the suptitle's font, loaded on first use
        self.dynamic = [*self.polys, *self.dots, *self.mains, self.suptitle]
        for a in self.dynamic:
            a.set_visible(False)
        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        for a in self.dynamic:
            a.set_visible(True)

    def _update(self, poly, dots, mains, d: np.ndarray) -> None:
        s = self.surface(d)
        i, j = self.quads[:, 0], self.quads[:, 1]
        a, b, c, e = s[i, j, :3], s[i + 1, j, :3], s[i + 1, j + 1, :3], s[i, j + 1, :3]
        # Lambert shading of each quad: normal from its diagonals (pointing forward, +z).
        n = np.cross(e - b, c - a)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        shade = AMBIENT + (1 - AMBIENT) * np.clip(n @ LIGHT, 0.0, 1.0)
        mag = (s[i, j, 3] + s[i + 1, j, 3] + s[i + 1, j + 1, 3] + s[i, j + 1, 3]) / 4
        rgba = self.cmap(self.norm(mag))
        rgba[:, :3] *= shade[:, None]
        quads = np.stack([a, b, c, e], axis=1)[..., [0, 2, 1]]  # head (x, y, z) -> (x, -z, y)
        quads[..., 1] *= -1
        poly.set_verts(quads)
        poly.set_facecolor(rgba)
        p = self.neutral + d
        dots.set_data_3d(p[self.rest_idx, 0], -p[self.rest_idx, 2], p[self.rest_idx, 1])
        mains.set_data_3d(p[self.main_idx, 0], -p[self.main_idx, 2], p[self.main_idx, 1])

    def draw(self, measured: np.ndarray, model: np.ndarray, title: str) -> None:
        """Update the dynamic artists (a full draw, e.g. by savefig, then shows them)."""
        self.suptitle.set_text(title)
        for p, d in enumerate((measured, model)):
            self._update(self.polys[p], self.dots[p], self.mains[p], d)

    def rgb(self) -> np.ndarray:
        """Blit: static background, then the surfaces and markers of this frame; the title is
        stamped with Pillow (:meth:`_stamp_title`)."""
        self.canvas.restore_region(self.background)
        for p, ax in enumerate(self.axes):
            self.polys[p].do_3d_projection()
            for artist in (self.polys[p], self.dots[p], self.mains[p]):
                ax.draw_artist(artist)
        rgba = np.asarray(self.canvas.buffer_rgba())
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
    built and its static parts rendered once; each frame updates the surfaces, markers and
    caption and blits them onto that background (Agg buffer), so frames cost a fraction of a
    full draw and a still of any frame reuses the same figure.
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

    def frames(self, captions: Sequence[str]) -> Iterator[np.ndarray]:
        """All frames in order (one in memory at a time), one caption each."""
        if len(captions) != len(self):
            raise InputError(f"animation: {len(captions)} captions for {len(self)} frames")
        for i, c in enumerate(captions):
            yield self.frame(i, c)

    def still(self, i: int, caption: str) -> Figure:
        """Frame i as a Figure (for a PNG/PDF still); draw no frames after taking it."""
        self._r.draw(self.measured[i], self.model[i], caption)
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
    'medium' at about the same file size on the study's animations) with bit-exact flags, one
    thread and no metadata, so a rerun is byte-identical; odd frame sizes are padded by one pixel.
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
