"""Shared figure style: colour-blind-safe colour cycles and small helpers."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd
from matplotlib.ticker import LogFormatter, ScalarFormatter

from facemotion.errors import InputError

# Paul Tol's "bright" qualitative scheme (colour-blind safe), then "muted" for more series.
QUALITATIVE = ("#4477AA", "#EE6677", "#228833", "#CCBB44", "#66CCEE", "#AA3377", "#BBBBBB",
               "#332288", "#117733", "#999933", "#882255", "#44AA99", "#DDCC77", "#CC6677")
LINESTYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def colour(i: int) -> str:
    return QUALITATIVE[i % len(QUALITATIVE)]


def require_columns(df: pd.DataFrame, columns, what: str) -> None:
    """One-line error naming the table and the columns it lacks."""
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise InputError(f"{what}: table lacks columns {missing} (has {list(df.columns)})")


def require_tables(tables: Mapping[str, pd.DataFrame], columns, what: str) -> None:
    if not tables:
        raise InputError(f"{what}: no tables to plot")
    for name, df in tables.items():
        require_columns(df, columns, f"{what} [{name}]")


class _PlainLogFormatter(LogFormatter):
    """LogFormatter's choice of which ticks to label, written as plain numbers (0.5, 2)."""

    def __call__(self, x, pos=None):
        return f"{x:g}" if super().__call__(x, pos) else ""


def set_title(ax, text: str, **kwargs):
    """``ax.set_title`` at the title's default place (y = 1, ``pad`` points above the axes)
    without matplotlib's automatic lift over top-side tick labels and the y axis's offset text
    (that check measured every y tick label at each draw: about 5 CPU-s of a default study).
    No figure here puts tick labels on top, and a linear y axis gets no offset text (its tick
    labels carry the whole numbers: 100.001, not +1e2 above the axes, under the title).
    Tested: every title clear of every other text."""
    fmt = ax.yaxis.get_major_formatter()
    if isinstance(fmt, ScalarFormatter):
        fmt.set_useOffset(False)
        fmt.set_scientific(False)
    return ax.set_title(text, y=1.0, **kwargs)


def fixed_layout(fig, *, left: float, right: float, bottom: float, top: float,
                 wgap: float = 0.0, hgap: float = 0.0) -> None:
    """Place the figure's grid of subplots (``fig.subplots``, on a figure without a layout
    engine) by margins and gaps in inches: from the figure's edges to the panels' frames, and
    between the frames of neighbouring panels.

    Instead of matplotlib's constrained layout, which measures every tick label and title of
    every panel in two passes at each draw and makes ``savefig`` draw the whole figure once
    more before the real draw: half or more of a simple figure's CPU. The figures here know
    their texts (tick labels of a few characters, one or two label lines, the number of note
    lines), so the caller sets the room they need from the figure's size and content; the
    figure tests check that no text leaves the figure or overlaps another."""
    if fig.get_layout_engine() is not None:
        raise ValueError("fixed_layout: the figure has a layout engine")
    nrows, ncols = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
    w, h = fig.get_size_inches()
    cell_w = (w - left - right - wgap * (ncols - 1)) / ncols
    cell_h = (h - top - bottom - hgap * (nrows - 1)) / nrows
    if cell_w <= 0 or cell_h <= 0:
        raise ValueError(f"fixed_layout: margins leave no room for the panels of a "
                         f"{w:g} x {h:g} in figure")
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wgap / cell_w, hspace=hgap / cell_h)


def save_renderer(fig):
    """The renderer that saving ``fig`` as PNG (``provenance.figure_bytes``) draws with, for
    measuring texts before the figure is saved: the figure gets an Agg canvas at the saved
    resolution, whose renderer ``savefig`` reuses, and with it matplotlib's cache of the text
    extents measured here (on another renderer every text is laid out again at the draw)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from facemotion.plots.save import FIGURE_DPI

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.set_dpi(FIGURE_DPI)
    return fig.canvas.get_renderer()


def yaxis_width(*axes) -> float:
    """Inches the y axes' tick labels and labels take left of their frames (the widest of
    ``axes``), measured at the figure's current layout: the one variable a fixed layout
    measures (tick labels are 1 to 5 characters wide), axis by axis and once, instead of
    constrained layout's passes over every text of the figure."""
    renderer = save_renderer(axes[0].figure)
    room = 0.0
    for ax in axes:
        bb = ax.yaxis.get_tightbbox(renderer)
        if bb is not None:
            room = max(room, (ax.get_window_extent(renderer).x0 - bb.x0) / ax.figure.dpi)
    return room


def ticks_in_view(*axes) -> None:
    """Each axis's ticks (major and minor) fixed at the ones its locator places inside the
    view, once the layout is final (the locators pick their ticks for the axes' size).

    Locators also return ticks beyond the limits (a log axis's minor locator, whole decades),
    and at every draw matplotlib makes a tick object (two marks, a grid line, two labels) for
    each before dropping the ones out of view. The same ticks are drawn, as before."""
    import numpy as np
    from matplotlib.ticker import FixedLocator, NullLocator

    for ax in axes:
        ax.apply_aspect()
        ax.get_xlim(), ax.get_ylim()  # autoscaled limits, if pending
        for axis in (ax.xaxis, ax.yaxis):
            transform = axis.get_transform()
            lo, hi = sorted(transform.transform(np.asarray(axis.get_view_interval())))
            tol = 1e-10 * (hi - lo)  # as matplotlib's own test of a tick in view
            for ticker in (axis.major, axis.minor):
                if isinstance(ticker.locator, (NullLocator, FixedLocator)):
                    continue
                locs = np.asarray(ticker.locator(), dtype=float)
                t = transform.transform(locs) if locs.size else locs
                keep = locs[(t >= lo - tol) & (t <= hi + tol)]
                ticker.locator = FixedLocator(keep.tolist())
                ticker.locator.set_axis(axis)


def plain_log_labels(axis) -> None:
    """Plain numbers (0.5, 1, 2) on a log axis; minor ticks labelled when few decades show."""
    axis.set_major_formatter(_PlainLogFormatter(labelOnlyBase=False))
    axis.set_minor_formatter(_PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.5)))


def _extent(artist, renderer, pad: float = 1.0):
    """Window extent of an artist; of an annotation, its text alone (not its arrow)."""
    from matplotlib.text import Annotation, Text

    if isinstance(artist, Annotation):
        return Text.get_window_extent(artist, renderer).padded(pad)
    return artist.get_window_extent(renderer).padded(pad)


def keep_legible(fig, texts, inside=None, avoid=()) -> list:
    """Remove texts that would overlap an earlier one (``texts`` in priority order), stick
    out of the axes ``inside`` or overlap an artist in ``avoid`` (e.g. the legend), measured
    from the rendered text extents. Returns the texts kept.

    Only what the extents depend on is computed (the layout, the axes' aspect, the
    annotations' positions), not a whole draw: saving the figure draws it anyway."""
    from matplotlib.text import Annotation

    renderer = save_renderer(fig)
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    for ax in fig.axes:
        ax.apply_aspect()
    for t in [*texts, *avoid]:
        if isinstance(t, Annotation):
            t.update_positions(renderer)
    box = inside.get_window_extent(renderer) if inside is not None else None
    blocked = [_extent(a, renderer) for a in avoid if a is not None]
    kept = []
    for t in texts:
        e = _extent(t, renderer)
        if (box is not None and not (box.x0 <= e.x0 and e.x1 <= box.x1 and box.y0 <= e.y0
                                     and e.y1 <= box.y1)) or any(e.overlaps(b) for b in blocked):
            t.remove()
            continue
        blocked.append(e)
        kept.append(t)
    return kept


def figure_titles(fig) -> list[str]:
    """The figure's title texts: its suptitle, then each axes' titles (left, centre, right)."""
    out = []
    sup = getattr(fig, "_suptitle", None)
    if sup is not None and sup.get_text():
        out.append(sup.get_text())
    for ax in fig.axes:
        out += [t for t in (ax.get_title(loc=loc) for loc in ("left", "center", "right")) if t]
    return out


def name_figure(fig, name: str) -> None:
    """Make a figure of one dataset say which: unless a title already names it, the suptitle
    (else the first titled axes' title, else a new suptitle) is prefixed with ``name:``."""
    if any(name in t for t in figure_titles(fig)):
        return
    sup = getattr(fig, "_suptitle", None)
    if sup is not None and sup.get_text():
        sup.set_text(f"{name}: {sup.get_text()}")
        return
    for ax in fig.axes:
        for loc in ("center", "left", "right"):
            if ax.get_title(loc=loc):
                ax.set_title(f"{name}: {ax.get_title(loc=loc)}", loc=loc)
                return
    fig.suptitle(name)
