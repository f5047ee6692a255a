"""Where samples were missing and where they were filled: a raster over time per marker."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from facemotion.errors import InputError
from facemotion.plots.style import fixed_layout, set_title, ticks_in_view, yaxis_width

MISSING_COLOUR = "#EE6677"  # red: missing and left unfilled
FILLED_COLOUR = "#4477AA"  # blue: filled (interpolated or reconstructed)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a 1-D boolean array as (start, stop) index pairs, stop exclusive."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))


def plot_gaps(time_s, missing, filled, labels: Sequence[str], sentence_bounds=None,
              max_all: int = 30, max_rows: int = 40) -> Figure:
    """Raster of missing (red) and filled (blue) samples over time, one row per marker.

    missing and filled are (frames, markers) bool; a sample that is both is drawn as filled.
    Each run of samples is one bar from the run's first sample time to its last plus one frame
    interval, so a single flagged frame stays visible. With more than ``max_all`` markers only
    markers with any flagged sample get a row, and at most ``max_rows`` of them (those with
    the most flagged samples, in label order), so the rows stay legible with thousands of
    markers; the figure says how many were left out (all are in the gap report table).
    """
    t = np.asarray(time_s, dtype=float)
    missing = np.asarray(missing, dtype=bool)
    filled = np.asarray(filled, dtype=bool)
    labels = [str(s) for s in labels]
    shape = (t.size, len(labels))
    if missing.shape != shape or filled.shape != shape:
        raise InputError(f"gap raster: missing {missing.shape} and filled {filled.shape} must be "
                         f"(frames, markers) = {shape}")
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    flagged = missing | filled
    show, n_flagged_shown = rows_shown(flagged, len(labels) > max_all, max_rows)
    nrows = max(show.size, 1)
    fig = Figure(figsize=(10.0, min(2.2 + 0.16 * nrows, 14.0)))
    ax = fig.subplots()
    only_missing = missing & ~filled
    _draw_runs(ax, t, dt, only_missing, filled, show)
    if sentence_bounds is not None:
        for b in np.asarray(sentence_bounds, dtype=float):
            ax.axvline(b, color="0.6", lw=0.6, alpha=0.6, zorder=0)
    ax.set_yticks(np.arange(show.size), [labels[j] for j in show],
                  fontsize=7 if show.size > 25 else 8)
    ax.set_ylim(nrows - 0.5, -0.5)
    if t.size:
        ax.set_xlim(t[0], t[-1] + dt)
    ax.set_xlabel("time (s, sentences concatenated)")
    ax.set_ylabel("marker")
    title = _title(only_missing, filled, show, n_flagged_shown, len(labels))
    if show.size == 0:
        ax.text(0.5, 0.5, f"no missing or filled samples in any of the {len(labels)} markers",
                transform=ax.transAxes, ha="center", va="center")
    set_title(ax, title, fontsize=9.5)
    ax.grid(True, axis="x", alpha=0.3)
    pad = 0.04  # inches from the figure's edge, as constrained layout's
    fig.legend(handles=[Patch(color=MISSING_COLOUR, label="missing (not filled)"),
                        Patch(color=FILLED_COLOUR, label="filled"),
                        Line2D([], [], color="0.6", lw=0.8, label="sentence start")],
               loc="lower center", bbox_to_anchor=(0.5, pad / fig.get_figheight()), ncols=3,
               fontsize=8, frameon=False)
    # fixed layout (inches): the title's lines above, the x axis and the legend's row below,
    # the measured marker labels and axis label on the left
    margins = {"right": 0.15, "bottom": 0.77, "top": 0.1 + 0.155 * (title.count("\n") + 1)}
    fixed_layout(fig, left=0.5, **margins)
    fixed_layout(fig, left=yaxis_width(ax) + pad, **margins)
    ticks_in_view(ax)
    return fig


def rows_shown(flagged: np.ndarray, flagged_only: bool, max_rows: int) -> tuple[np.ndarray, int]:
    """The markers given a row (all, or with ``flagged_only`` those with a flagged sample; at
    most ``max_rows``: the most flagged, in label order) and how many were eligible."""
    show = np.flatnonzero(flagged.any(axis=0)) if flagged_only else np.arange(flagged.shape[1])
    eligible = show.size
    if show.size > max_rows:
        counts = flagged[:, show].sum(axis=0)
        top = np.argsort(-counts, kind="stable")[:max_rows]
        show = np.sort(show[top])
    return show, eligible


def _draw_runs(ax, t: np.ndarray, dt: float, only_missing: np.ndarray, filled: np.ndarray,
               show: np.ndarray) -> None:
    """One bar per run of missing (red) or filled (blue) samples, a row per shown marker."""
    for row, j in enumerate(show):
        for mask, c in ((only_missing[:, j], MISSING_COLOUR), (filled[:, j], FILLED_COLOUR)):
            r = runs(mask)
            if r:
                bars = [(t[a], t[b - 1] + dt - t[a]) for a, b in r]
                ax.broken_barh(bars, (row - 0.4, 0.8), facecolors=c, edgecolors=c,
                               linewidths=0.4, gid="missing" if c == MISSING_COLOUR else "filled")


def _title(only_missing: np.ndarray, filled: np.ndarray, show: np.ndarray,
           n_flagged_shown: int, n_labels: int) -> str:
    """The counts of filled and missing samples, and which markers the rows show."""
    flagged = only_missing | filled
    any_flag = flagged.any(axis=0)
    hidden = n_labels - show.size
    n_miss, n_fill = int(only_missing.sum()), int(filled.sum())
    frac = flagged.sum() / max(flagged.size, 1)
    title = (f"Missing and filled samples: {n_fill} filled, {n_miss} left missing "
             f"({100 * frac:.2f}% of {flagged.size} samples)")
    if n_flagged_shown > show.size:
        title += (f"\nthe {show.size} markers with the most flagged samples are shown, of "
                  f"{int(any_flag.sum())} with any; all {n_labels} are in the gap report "
                  "table")
    elif hidden and show.size:
        title += (f"\nonly the {show.size} markers with flagged samples are shown; "
                  f"{hidden} markers with no missing samples not shown")
    return title
