"""Fields over the face: interpolation of per-marker values on a grid and frontal-view panels.

Head axes: x from the talker's right to left, y up, z forward. The frontal view plots (x, y)
as is, so the face appears as seen by someone facing the talker: the talker's right (negative x)
is on the viewer's left.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib import patheffects
from matplotlib.colors import Normalize

from facemotion.errors import InputError

# Colour-blind-safe colours (Paul Tol's "bright" and "vibrant" schemes).
MAIN_COLOUR = "#EE6677"  # red: main markers
NEGATIVE_COLOUR = "#0077BB"  # blue: negative subregions
MARKER_COLOUR = "#222222"
FIELD_CMAP = "Greys"  # darker for larger values, as in the paper's region maps
HALO = [patheffects.withStroke(linewidth=2.0, foreground="white")]


def as_neutral(neutral, labels: Sequence[str]) -> tuple[np.ndarray, list[str]]:
    """Check a (n, 3) neutral position array against its n labels; labels become strings."""
    neutral = np.asarray(neutral, dtype=float)
    labels = [str(s) for s in labels]
    if neutral.ndim != 2 or neutral.shape[1] != 3:
        raise InputError(f"neutral positions must be (markers, 3) mm, got shape {neutral.shape}")
    if neutral.shape[0] != len(labels):
        raise InputError(f"{len(labels)} marker labels but {neutral.shape[0]} neutral positions")
    if not np.all(np.isfinite(neutral)):
        bad = [labels[i] for i in np.flatnonzero(~np.isfinite(neutral).all(axis=1))]
        raise InputError(f"neutral positions are not finite for markers {bad}")
    return neutral, labels


def label_index(labels: Sequence[str], wanted: Sequence[str], what: str = "marker") -> np.ndarray:
    """Positions of ``wanted`` labels in ``labels``, with an error naming any that are absent."""
    pos = {s: i for i, s in enumerate(labels)}
    missing = [str(w) for w in wanted if str(w) not in pos]
    if missing:
        raise InputError(f"{what} labels {missing} not among the {len(labels)} face markers")
    return np.array([pos[str(w)] for w in wanted], dtype=int)


def face_grid(xy: np.ndarray, grid_n: int) -> tuple[np.ndarray, np.ndarray]:
    """A grid_n x grid_n grid spanning the (x, y) extent of the markers (meshgrid, 'xy')."""
    if grid_n < 2:
        raise InputError(f"grid_n must be at least 2, got {grid_n}")
    x = np.linspace(xy[:, 0].min(), xy[:, 0].max(), grid_n)
    y = np.linspace(xy[:, 1].min(), xy[:, 1].max(), grid_n)
    return np.meshgrid(x, y)


def interpolate_field(xy: np.ndarray, values: np.ndarray, grid_n: int = 100
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Piecewise-cubic (Clough-Tocher, scipy griddata 'cubic') interpolation of per-marker
    values over a grid on the markers' (x, y) extent; NaN outside the markers' convex hull.

    values may be (n,) or (n, m); the result Z is (grid_n, grid_n) or (grid_n, grid_n, m).
    """
    xy = np.asarray(xy, dtype=float)[:, :2]
    values = np.asarray(values, dtype=float)
    if values.shape[0] != xy.shape[0]:
        raise InputError(f"{values.shape[0]} values for {xy.shape[0]} marker positions")
    if xy.shape[0] < 3:
        raise InputError(f"need at least 3 markers to interpolate over the face, got {len(xy)}")
    gx, gy = face_grid(xy, grid_n)
    from scipy.interpolate import griddata  # here: scipy costs ~0.6 s to import

    z = griddata(xy, values, (gx, gy), method="cubic", fill_value=np.nan)
    return gx, gy, z


def interpolate_at(xy: np.ndarray, values: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The same interpolant as :func:`interpolate_field`, evaluated at arbitrary (x, y) points
    (e.g. the markers themselves, where it returns their values)."""
    xy = np.asarray(xy, dtype=float)[:, :2]
    points = np.asarray(points, dtype=float)[..., :2]
    from scipy.interpolate import griddata  # here: scipy costs ~0.6 s to import

    return griddata(xy, np.asarray(values, dtype=float), points, method="cubic",
                    fill_value=np.nan)


def symmetric_limits(*arrays: np.ndarray, floor: float = 1.0) -> float:
    """Largest finite value of the arrays, at least ``floor`` (for a shared colour scale)."""
    m = floor
    for a in arrays:
        a = np.asarray(a, dtype=float)
        if np.isfinite(a).any():
            m = max(m, float(np.nanmax(a)))
    return m


def setup_frontal(ax, xy: np.ndarray, pad: float = 0.06) -> None:
    """Equal-aspect frontal view with fixed limits and labelled mm axes."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = np.maximum(hi - lo, 1e-9)
    ax.set_xlim(lo[0] - pad * span[0], hi[0] + pad * span[0])
    ax.set_ylim(lo[1] - pad * span[1], hi[1] + pad * span[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm), talker's right → left")
    ax.set_ylabel("y (mm), up")


def grid_extent(gx: np.ndarray, gy: np.ndarray) -> tuple[float, float, float, float]:
    """imshow ``extent`` of a regular meshgrid (as :func:`face_grid` makes): the grid nodes
    are the pixel centres, so the image reaches half a cell beyond the outer nodes."""
    dx = (gx[0, -1] - gx[0, 0]) / max(gx.shape[1] - 1, 1)
    dy = (gy[-1, 0] - gy[0, 0]) / max(gy.shape[0] - 1, 1)
    return (gx[0, 0] - dx / 2, gx[0, -1] + dx / 2, gy[0, 0] - dy / 2, gy[-1, 0] + dy / 2)


def draw_field(ax, xy: np.ndarray, values: np.ndarray, norm: Normalize, grid_n: int,
               cmap: str = FIELD_CMAP, negative_below: float = 0.0, field=None):
    """Draw an interpolated per-marker field: grey-scale for the positive part (darker = larger),
    subregions below ``-negative_below`` hatched and outlined in blue. Returns the image artist
    (for a colorbar).

    ``field``: the ``(gx, gy, z)`` of :func:`interpolate_field` for these values, if already
    computed (one call for all the panels of a figure shares the triangulation).

    The grid is regular, so the field is one image (pixel centres on the grid nodes, colours
    interpolated bilinearly between them, as a Gouraud-shaded mesh of the grid would, at a
    fraction of the cost of drawing its 2 (n-1)^2 triangles); outside the markers' convex
    hull (NaN) it is transparent.
    """
    gx, gy, z = field if field is not None else interpolate_field(xy, values, grid_n)
    shown = np.ma.masked_invalid(np.clip(z, norm.vmin, None))
    image = ax.imshow(shown, cmap=cmap, norm=norm, origin="lower", extent=grid_extent(gx, gy),
                      interpolation="bilinear", interpolation_stage="rgba", aspect="auto")
    level = -abs(negative_below)
    if np.isfinite(z).any() and np.nanmin(z) < level:
        zz = np.ma.masked_invalid(z)
        lo = float(np.nanmin(z))
        cs = ax.contourf(gx, gy, zz, levels=[lo - 1.0, level], colors="none", hatches=["////"])
        cs.set_edgecolor(NEGATIVE_COLOUR)
        cs.set_linewidth(0.0)
        ax.contour(gx, gy, zz, levels=[level], colors=NEGATIVE_COLOUR, linewidths=0.8)
    return image


def draw_markers(ax, xy: np.ndarray, labels: Sequence[str], highlight: Sequence[str] = (),
                 label_highlight: bool = True, size: float = 6.0, dots: bool = True) -> None:
    """Markers as small dots (``dots``); highlighted ones as larger red dots with labels."""
    if dots:
        ax.scatter(xy[:, 0], xy[:, 1], s=size, c=MARKER_COLOUR, linewidths=0, zorder=3)
    if len(highlight):
        idx = label_index(labels, highlight)
        ax.scatter(xy[idx, 0], xy[idx, 1], s=size * 5, c=MAIN_COLOUR, edgecolors="white",
                   linewidths=0.6, zorder=4)
        if label_highlight:
            # beside the marker, turned inwards near the right or top edge of the view (set
            # the view first) so that the label stays inside the panel
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            for i in idx:
                right = (xy[i, 0] - x0) > 0.7 * (x1 - x0)
                top = (xy[i, 1] - y0) > 0.85 * (y1 - y0)
                ax.annotate(labels[i], xy[i], xytext=(-3 if right else 3, -3 if top else 3),
                            textcoords="offset points", ha="right" if right else "left",
                            va="top" if top else "bottom", fontsize=8, color=MAIN_COLOUR,
                            fontweight="bold", zorder=5, path_effects=HALO)


def mesh_values(placed, xy: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-vertex values of a placed face mesh: a marker's own value at its vertex; at the
    other vertices the markers' cubic interpolant (NaN outside the markers' convex hull)."""
    values = np.asarray(values, dtype=float)
    out = np.full(len(placed.positions), np.nan)
    own = placed.marker_index >= 0
    out[own] = values[placed.marker_index[own]]
    if (~own).any():
        out[~own] = interpolate_at(xy, values, placed.positions[~own, :2])
    return out


def visible_triangles(placed, vertex_values: np.ndarray | None = None) -> np.ndarray:
    """The placed mesh's front-facing triangles with a value at all three vertices, back to
    front (painter's order by mean depth z)."""
    from facemotion.plots.face_mesh import front_facing

    tris = front_facing(placed.positions[:, :2], placed.triangles)
    if vertex_values is not None:
        tris = tris[np.isfinite(vertex_values[tris]).all(axis=1)]
    return tris[np.argsort(placed.positions[tris, 2].mean(axis=1), kind="stable")]


def draw_mesh_field(ax, placed, xy: np.ndarray, values: np.ndarray, norm: Normalize,
                    cmap: str = FIELD_CMAP, negative_below: float = 0.0):
    """Draw a per-marker field on the face mesh's triangles (Gouraud shading between the
    vertex values, see :func:`mesh_values`), in the style of :func:`draw_field`: grey-scale
    for the positive part, subregions below ``-negative_below`` hatched and outlined in blue.
    Returns the artist (for a colorbar)."""
    from matplotlib.tri import Triangulation

    v = mesh_values(placed, xy, values)
    tris = visible_triangles(placed, v)
    if len(tris) == 0:
        raise InputError("face mesh: no triangle of the mesh lies within the markers")
    p = placed.positions
    tri = Triangulation(p[:, 0], p[:, 1], tris)
    z = np.where(np.isfinite(v), v, 0.0)  # vertices off the drawn triangles are never used
    art = ax.tripcolor(tri, np.clip(z, norm.vmin, None), shading="gouraud", cmap=cmap,
                       norm=norm, rasterized=True)
    ax.triplot(tri, color="0.55", lw=0.15, alpha=0.5, zorder=1.5)
    level = -abs(negative_below)
    used = np.unique(tris)
    if z[used].min() < level:
        cs = ax.tricontourf(tri, z, levels=[float(z[used].min()) - 1.0, level], colors="none",
                            hatches=["////"])
        cs.set_edgecolor(NEGATIVE_COLOUR)
        cs.set_linewidth(0.0)
        ax.tricontour(tri, z, levels=[level], colors=NEGATIVE_COLOUR, linewidths=0.8)
    return art
