"""Kinematic region maps (paper Figs. 4-7) and maps of the orthogonal directions (rows of R).

Both draw, per main marker, a per-marker coefficient interpolated over the frontal face
(x as is: the talker's right on the viewer's left), grey-scale with darker = larger, on one
colour scale shared by all panels; negative subregions are hatched and outlined in blue.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import FixedLocator, NullFormatter

from facemotion.errors import InputError
from facemotion.plots.face_mesh import FaceMesh, place_mesh
from facemotion.plots.facemap import (
    NEGATIVE_COLOUR,
    as_neutral,
    draw_field,
    draw_markers,
    draw_mesh_field,
    interpolate_field,
    label_index,
    mesh_values,
    setup_frontal,
    symmetric_limits,
    visible_triangles,
)
from facemotion.plots.style import set_title

#: above this many markers they are not drawn as dots (the mesh or field shows the layout)
MAX_DOTS = 150


def region_coefficients(labels: Sequence[str], X: pd.DataFrame) -> np.ndarray:
    """Per-marker fit coefficients, one row per main marker (k, n) in the order of ``labels``.

    Row i: the main marker i itself 1, the other main markers 0, and each secondary marker j
    X[main_i, j], the weight of main marker i in the prediction of j (x_j = sum_i X_ij a_i,
    X = R11^-1 R12, L&M Sec. III, eqs. 3-4).
    """
    labels = [str(s) for s in labels]
    mains = [str(s) for s in X.index]
    secondary = [str(s) for s in X.columns]
    overlap = sorted(set(mains) & set(secondary))
    if overlap:
        raise InputError(f"coefficient table: markers {overlap} are both main and secondary")
    im = label_index(labels, mains, "main marker")
    isec = label_index(labels, secondary, "secondary marker")
    covered = len(mains) + len(secondary)
    if covered != len(labels):
        rest = sorted(set(labels) - set(mains) - set(secondary))
        raise InputError(f"coefficient table lacks markers {rest} (neither main nor secondary)")
    C = np.zeros((len(mains), len(labels)))
    C[np.arange(len(mains)), im] = 1.0
    C[:, isec] = X.to_numpy(dtype=float)
    return C


def orthogonal_direction_coefficients(R: np.ndarray, order_labels: Sequence[str],
                                      labels: Sequence[str], n_pivots: int) -> np.ndarray:
    """Rows of R divided by their diagonal, reordered from pivot order to ``labels`` order.

    A P = Q R (L&M Sec. III, unnumbered): column j of A P has component R[i, j] along the i-th
    orthogonal direction q_i; R[i, j] / R[i, i] is marker j's motion along q_i relative to
    pivot i's.
    """
    R = np.asarray(R, dtype=float)
    order_labels = [str(s) for s in order_labels]
    if R.ndim != 2 or R.shape[1] != len(order_labels):
        raise InputError(f"R must have one column per marker ({len(order_labels)}), "
                         f"got shape {R.shape}")
    if sorted(order_labels) != sorted(labels):
        raise InputError("pivot-order labels and face marker labels are not the same set: "
                         f"{sorted(set(order_labels) ^ set(labels))}")
    n_pivots = min(int(n_pivots), R.shape[0], R.shape[1])
    if n_pivots < 1:
        raise InputError(f"n_pivots must be at least 1, got {n_pivots}")
    col = label_index(order_labels, labels)
    out = np.empty((n_pivots, len(labels)))
    for i in range(n_pivots):
        if R[i, i] == 0:
            raise InputError(f"R[{i}, {i}] is zero (pivot {order_labels[i]}): rank-deficient")
        out[i] = R[i, col] / R[i, i]
    return out


def _grid_shape(n: int, max_cols: int = 5) -> tuple[int, int]:
    ncols = min(n, max_cols)
    return math.ceil(n / ncols), ncols


def _field_panels(neutral: np.ndarray, labels: list[str], coeffs: np.ndarray,
                  mains: list[str], titles: list[str], grid_n: int, suptitle: str,
                  cbar_label: str, highlight_all: bool, negative_below: float,
                  mesh: FaceMesh | None = None) -> Figure:
    xy = neutral[:, :2]
    placed = place_mesh(mesh, neutral, labels) if mesh is not None else None
    extent = xy
    if placed is not None:
        drawn = visible_triangles(placed, mesh_values(placed, xy, coeffs[0]))
        extent = np.vstack([xy, placed.positions[np.unique(drawn), :2]])
    dots = len(labels) <= MAX_DOTS  # a dense layout: the mesh shows where the points are
    nrows, ncols = _grid_shape(len(mains))
    norm = Normalize(vmin=0.0, vmax=symmetric_limits(coeffs, floor=1.0))
    thr = negative_below * norm.vmax
    any_negative = bool((coeffs < -thr).any())
    if placed is not None:
        suptitle += (f"\non the face mesh {Path(mesh.name).name} ({len(placed.positions)} "
                     f"vertices, {int((placed.marker_index >= 0).sum())} of them markers; "
                     "values between markers interpolated on its triangles)")
    width = 2.7 * ncols + 1.0
    # wrapped to the figure's width (about 11 characters an inch at the suptitle's 12 pt)
    suptitle = "\n".join(textwrap.fill(line, int(width * 10.5))
                         for line in suptitle.split("\n"))
    suptitle_lines = suptitle.count("\n") + 1
    height = 3.0 * nrows + 0.6 + 0.3 * (suptitle_lines - 1)
    fig = Figure(figsize=(width, height))
    margins = {"left": 0.75, "right": 1.1, "bottom": 0.62 + (0.22 if any_negative else 0.0),
               "top": 0.22 + 0.24 * suptitle_lines + 0.3}
    axes = _panel_grid(fig, nrows, ncols, **margins)
    art = None
    # one interpolation for all panels: they share the triangulation (same values as one each)
    fields = interpolate_field(xy, coeffs.T, grid_n) if placed is None else None
    for p, ax in enumerate(axes):
        if p >= len(mains):
            ax.set_axis_off()
            continue
        if placed is not None:
            art = draw_mesh_field(ax, placed, xy, coeffs[p], norm, negative_below=thr)
        else:
            gx, gy, z = fields
            art = draw_field(ax, xy, coeffs[p], norm, grid_n, negative_below=thr,
                             field=(gx, gy, z[..., p]))
        others = [m for m in mains if m != mains[p]] if highlight_all else []
        _finish_panel(ax, xy, labels, mains[p], others, extent, titles[p], dots)
    _ticks_in_view(axes[: len(mains)])
    if art is not None:
        _colour_bar(fig, art, cbar_label, **margins)
    if any_negative:
        fig.legend(handles=[Patch(facecolor="white", edgecolor=NEGATIVE_COLOUR, hatch="////",
                                  label=f"negative: below {-thr:.2g} (values < 0 are white)")],
                   loc="lower right", bbox_to_anchor=(1 - 0.05 / width, 0.02 / height),
                   fontsize=8, frameon=False)
    fig.suptitle(suptitle, y=1 - 0.12 / height, va="top")
    return fig


def _panel_grid(fig: Figure, nrows: int, ncols: int, left: float, right: float,
                bottom: float, top: float) -> np.ndarray:
    """The panels (flat) in a fixed layout in inches, margins for the tick labels and label
    (left, below, with the legend), the suptitle and panel titles (above) and the colour bar
    (right)."""
    # matplotlib's constrained layout measured every tick label of every panel in two passes:
    # half of the figure's cost
    width, height = fig.get_size_inches()
    # not shared: every panel gets the same limits (setup_frontal), and an inner panel's hidden
    # tick labels get a formatter of their own that does nothing (_finish_panel)
    cell_w = (width - left - right) / ncols
    cell_h = (height - top - bottom) / nrows
    gap_w, gap_h = 0.25, 0.42  # between panels: tick marks; a panel title
    return np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False, gridspec_kw={
        "left": left / width, "right": 1 - right / width, "bottom": bottom / height,
        "top": 1 - top / height, "wspace": gap_w / (cell_w - gap_w),
        "hspace": gap_h / (cell_h - gap_h)})).ravel()


def _finish_panel(ax, xy: np.ndarray, labels: list[str], main: str, others: list[str],
                  extent: np.ndarray, title: str, dots: bool) -> None:
    """The other main markers ringed, the face's frame, the markers, the title, outer ticks."""
    if others:
        io = label_index(labels, others)
        ax.scatter(xy[io, 0], xy[io, 1], s=14, facecolors="none", edgecolors="#EE6677",
                   linewidths=0.7, zorder=4)
    setup_frontal(ax, extent)
    draw_markers(ax, xy, labels, highlight=[main], dots=dots)
    set_title(ax, title, fontsize=10)
    ax.label_outer()
    # the tick labels label_outer hid: not formatted again at every layout pass
    if not ax.get_subplotspec().is_last_row():
        ax.xaxis.set_major_formatter(NullFormatter())
    if not ax.get_subplotspec().is_first_col():
        ax.yaxis.set_major_formatter(NullFormatter())


def _colour_bar(fig: Figure, art, label: str, left: float, right: float, bottom: float,
                top: float) -> None:
    """The colour bar in the right margin, over the middle 80 % of the panels' height."""
    width, height = fig.get_size_inches()
    plot_h = 1 - (top + bottom) / height
    cax = fig.add_axes((1 - (right - 0.25) / width, bottom / height + 0.1 * plot_h,
                        0.15 / width, 0.8 * plot_h), label="<colorbar>")
    cb = fig.colorbar(art, cax=cax, extend="neither")
    cb.set_label(label)


def _ticks_in_view(axes) -> None:
    """The panels' ticks fixed in mm, the same step on both axes (the larger of the two
    matplotlib's locator picks: the maps have equal aspect, so the ticks are evenly spaced
    squares), only those inside the view.

    All panels show the same limits at the same size, so they get the same ticks. Each tick
    is an object of two marks, a grid line and two labels that matplotlib makes at every draw,
    also for the locator's ticks beyond the limits (dropped after): with 10 panels, about 60
    of ~170 a figure, and 40 more for y ticks twice as dense as the x ones."""
    first = axes[0]
    first.apply_aspect()  # the panel's size at draw time (equal aspect), which sets the ticks
    steps = [float(np.diff(axis.get_major_locator()()).max(initial=0.0))
             for axis in (first.xaxis, first.yaxis)]
    step = max(steps)
    for i, axis in enumerate((first.xaxis, first.yaxis)):
        lo, hi = sorted(axis.get_view_interval())
        locs = [float(v) for v in step * np.arange(np.ceil(lo / step - 1e-9),
                                                    np.floor(hi / step + 1e-9) + 1)]
        for ax in axes:
            (ax.xaxis, ax.yaxis)[i].set_major_locator(FixedLocator(locs))


def plot_region_maps(neutral, labels: Sequence[str], X: pd.DataFrame,
                     grid_n: int = 100, negative_below: float = 0.05,
                     mesh: FaceMesh | None = None) -> Figure:
    """Kinematic region of each main marker (paper Figs. 4-7): its fit coefficient for every
    marker (itself 1, other main markers 0, secondary j: X[main, j]) interpolated over the face.

    Negative subregions deeper than ``negative_below`` times the colour scale's maximum are
    hatched (shallower ones are estimation noise and would hatch most of the face).

    ``mesh``: a face mesh whose vertex labels are (some of) the markers (e.g. the canonical
    face model for MediaPipe landmarks): the maps are then drawn on its front-facing
    triangles, one value per vertex, instead of on a grid over the markers' convex hull.
    """
    neutral, labels = as_neutral(neutral, labels)
    C = region_coefficients(labels, X)
    mains = [str(s) for s in X.index]
    titles = [f"main marker {m}" for m in mains]
    return _field_panels(
        neutral, labels, C, mains, titles, grid_n,
        suptitle=(f"Kinematic regions of the k = {len(mains)} main markers: coefficient of each "
                  "main marker in the prediction of every marker (frontal view)"),
        cbar_label="fit coefficient (main marker = 1)", highlight_all=True,
        negative_below=negative_below, mesh=mesh)


def plot_orthogonal_directions(neutral, labels: Sequence[str], R: np.ndarray,
                               order_labels: Sequence[str], n_pivots: int = 4,
                               grid_n: int = 100, negative_below: float = 0.05,
                               mesh: FaceMesh | None = None) -> Figure:
    """How much each marker moves along the first ``n_pivots`` orthogonal directions q_i
    (rows of R, each divided by its diagonal entry), interpolated over the face (on ``mesh``'s
    triangles when given, as in :func:`plot_region_maps`)."""
    neutral, labels = as_neutral(neutral, labels)
    C = orthogonal_direction_coefficients(R, order_labels, labels, n_pivots)
    pivots = [str(s) for s in order_labels[: C.shape[0]]]
    titles = [f"q{i + 1}: pivot {m}" for i, m in enumerate(pivots)]
    return _field_panels(
        neutral, labels, C, pivots, titles, grid_n,
        suptitle=(f"Motion along the first {len(pivots)} orthogonal directions: "
                  "R[i, j] / R[i, i] (earlier pivots are 0)"),
        cbar_label="R[i, j] / R[i, i]", highlight_all=False,
        negative_below=negative_below, mesh=mesh)
