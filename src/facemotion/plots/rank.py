"""Rank of the markers: |r_kk| of each pivot against its order (paper Fig. 2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from facemotion.plots.facemap import HALO
from facemotion.plots.style import (
    MARKERS,
    colour,
    fixed_layout,
    keep_legible,
    plain_log_labels,
    require_tables,
    set_title,
    ticks_in_view,
    yaxis_width,
)

#: y-axis label per normalisation of R (the ``r_normalisation`` column of r_values.tsv)
_NORM_LABEL = {
    "none": "|r_kk|, 2-norm of the orthogonal component (mm, log scale)",
    "per_coordinate": "|r_kk| / sqrt(3M), RMS per coordinate (mm, log scale)",
    "per_frame": "|r_kk| / sqrt(M), RMS 3-D per frame (mm, log scale)",
}
#: below this fraction of a dataset's largest value, r_kk is numerically zero (an exact copy)
NUMERICAL_ZERO = 1e-9


def plot_r_values(tables: Mapping[str, pd.DataFrame],
                  tolerances: Sequence[float] = (0.25, 0.5, 1.0),
                  annotate_below: float = 0.5, max_annotations: int = 3,
                  column: str = "r_normalised",
                  flagged: Mapping[str, pd.DataFrame] | None = None) -> Figure:
    """|r_kk| of the pivots (``column``, mm) against pivot order, datasets overlaid, log y.

    Dashed horizontal lines mark the epsilon tolerances (|r_kk| <= ||R22||_2, so a pivot below
    a line is necessary, not sufficient, for the epsilon-rank to stop before it). Values below
    ``NUMERICAL_ZERO`` times the dataset's largest are listed as numerically zero instead of
    stretching the log axis (listed under the axes). For each dataset the last
    ``max_annotations`` (one if there are more than two datasets) pivots below
    ``annotate_below`` mm (the markers best explained by the others) are labelled, last
    first and datasets in turn, as long as a label overlaps no earlier label, the legend or a
    tolerance label and stays inside the axes; the others are left out rather than piled up.
    ``flagged``: per dataset, the first pivots mostly made up by gap filling (rows with
    ``order``, ``marker``, ``filled_fraction``): ringed in red and named under the axes.
    """
    require_tables(tables, ("order", "marker", column), "r values")
    fig = Figure(figsize=(7.0, 4.6))
    ax = fig.subplots()
    n_max, lows, zeros, candidates = _draw_curves(ax, tables, column, annotate_below,
                                                  max_annotations)
    ax.set_yscale("log")
    for t in sorted(tolerances):
        ax.axhline(t, color="0.35", ls="--", lw=0.8, zorder=0)
        ax.annotate(f"ε = {t:g} mm", (0.0, t), xycoords=("axes fraction", "data"),
                    xytext=(3, 2), textcoords="offset points", ha="left", va="bottom",
                    fontsize=7.5, color="0.3")
    if lows:
        # room under the lowest point for the labels of the last pivots
        ax.set_ylim(bottom=min(min(lows), min(tolerances, default=1.0)) / 4)
    note = "\n".join(x for x in (_zeros_note(zeros), _flag_rings(ax, tables, column, flagged))
                     if x)
    if note:
        fig.supxlabel(note, fontsize=7.5, color="0.3")
    ax.set_xlim(0.5, n_max + 0.5)
    ax.set_xlabel("pivot order (marker selected at step i of QR with column pivoting)")
    ax.set_ylabel(_y_label(tables, column))
    set_title(ax, "Independent motion of each pivot marker (diagonal of R)")
    ax.grid(True, which="major", alpha=0.3)
    plain_log_labels(ax.yaxis)
    legend = ax.legend(fontsize=8, loc="upper right")
    # fixed layout (inches): the title above, the note line under the axes, the measured y
    # tick labels and label on the left (before the labels that must stay inside the axes)
    margins = {"right": 0.1, "top": 0.25,
               "bottom": 0.48 + (0.05 + 0.15 * note.count("\n") + 0.15 if note else 0.0)}
    fixed_layout(fig, left=0.85, **margins)
    fixed_layout(fig, left=yaxis_width(ax) + 0.05, **margins)
    ticks_in_view(ax)
    texts = _label_last_pivots(ax, candidates, n_max)
    keep_legible(fig, texts, inside=ax, avoid=[legend, *ax.texts[:len(tolerances)]])
    return fig


#: Characters of the 7.5-point note under the axes that fit the 7-inch figure's width.
NOTE_CHARS = 120


def _flag_rings(ax, tables: Mapping[str, pd.DataFrame], column: str,
                flagged: Mapping[str, pd.DataFrame] | None) -> str:
    """Red rings on the mostly filled first pivots, and their note (one line a dataset)."""
    import textwrap

    lines = []
    for name, rows in (flagged or {}).items():
        if rows is None or len(rows) == 0 or name not in tables:
            continue
        df = tables[name].set_index("order")
        orders = rows["order"].to_numpy(dtype=int)
        ax.plot(orders, df.loc[orders, column].to_numpy(dtype=float), ls="none", marker="o",
                ms=9, mfc="none", mec="#c00000", mew=1.4, zorder=5)
        text = f"{name}: mostly made up by gap filling (red rings): " + "; ".join(
            f"pivot {int(r.order)} {r.marker} {100 * r.filled_fraction:.0f} % filled"
            for r in rows.itertuples())
        lines += textwrap.wrap(text, NOTE_CHARS, subsequent_indent="    ")
    return "\n".join(lines)


def _zeros_note(zeros: list[str]) -> str:
    """The note of the numerically zero pivots: one line while it fits the figure's width,
    else a line per dataset (each wrapped to the width)."""
    import textwrap

    if not zeros:
        return ""
    one = "numerically 0 (not on the log axis): " + "; ".join(zeros)
    if len(one) <= NOTE_CHARS:
        return one
    lines = ["numerically 0 (not on the log axis):"]
    for z in zeros:
        lines += textwrap.wrap(z, NOTE_CHARS, subsequent_indent="    ")
    return "\n".join(lines)


def _draw_curves(ax, tables: Mapping[str, pd.DataFrame], column: str, annotate_below: float,
                 max_annotations: int) -> tuple[int, list[float], list[str], list[list[tuple]]]:
    """Each dataset's |r_kk| against pivot order; the largest order, each dataset's smallest
    positive value, the numerically-zero pivots' note, and the pivots to label."""
    n_max = 1
    lows: list[float] = []
    zeros: list[str] = []
    candidates: list[list[tuple]] = []
    for d, (name, df) in enumerate(tables.items()):
        df = df.sort_values("order")
        order = df["order"].to_numpy(dtype=int)
        r = df[column].to_numpy(dtype=float)
        markers = df["marker"].astype(str).to_numpy()
        n_max = max(n_max, int(order.max()))
        c = colour(d)
        positive = r > NUMERICAL_ZERO * max(float(np.max(r)), 0.0)
        ax.plot(order, np.where(positive, r, np.nan), marker=MARKERS[d % len(MARKERS)],
                ms=3.5 if len(order) <= 100 else 1.5,
                lw=1.2, color=c, label=f"{name} ({len(order)} markers)")
        if (~positive).any():
            zeros.append(f"{name}: {', '.join(markers[~positive][:8])}"
                         + (" ..." if (~positive).sum() > 8 else ""))
        if positive.any():
            lows.append(float(r[positive].min()))
        per_dataset = max_annotations if len(tables) <= 2 else 1
        below = np.flatnonzero((r < annotate_below) & positive)[-per_dataset:][::-1]
        candidates.append([(i, order[i], r[i], markers[i], c) for i in below])
    return n_max, lows, zeros, candidates


def _y_label(tables: Mapping[str, pd.DataFrame], column: str) -> str:
    """The y label of the tables' R normalisation (two lines when long)."""
    norms = {str(v) for df in tables.values() if "r_normalisation" in df.columns
             for v in df["r_normalisation"].unique()}
    ylabel = (_NORM_LABEL.get(norms.pop(), column) if len(norms) == 1
              else f"{column} (mm, log scale)")
    if len(ylabel) > 40:  # two lines: one is longer than the axes are high
        ylabel = ylabel.replace(" (", "\n(", 1)
    return ylabel


def _label_last_pivots(ax, candidates: list[list[tuple]], n_max: int) -> list:
    """Labels of the last pivots below ``annotate_below``: below-left of a point near the right
    edge, above-right of the others (where a falling curve leaves room); datasets in turn."""
    texts = []
    for rank_j in range(max((len(c) for c in candidates), default=0)):
        for cands in candidates:
            if rank_j < len(cands):
                _, x, y, label, c = cands[rank_j]
                right = x > 0.75 * n_max
                dy = 7 + 16 * rank_j
                texts.append(ax.annotate(
                    label, (x, y), xytext=(-5, -dy) if right else (5, dy),
                    textcoords="offset points", fontsize=7.5, color=c,
                    ha="right" if right else "left", va="top" if right else "bottom",
                    path_effects=HALO,
                    arrowprops={"arrowstyle": "-", "color": c, "lw": 0.6,
                                "shrinkA": 0, "shrinkB": 2}))
    return texts
