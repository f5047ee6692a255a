"""Rank of the markers: |r_kk| of each pivot against its order (paper Fig. 2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from facemotion.plots.facemap import HALO
from facemotion.plots.style import MARKERS, colour, plain_log_labels, require_tables

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
                  column: str = "r_normalised") -> Figure:
    """|r_kk| of the pivots (``column``, mm) against pivot order, datasets overlaid, log y.

    Dashed horizontal lines mark the epsilon tolerances (|r_kk| <= ||R22||_2, so a pivot below
    a line is necessary, not sufficient, for the epsilon-rank to stop before it). Values below
    ``NUMERICAL_ZERO`` times the dataset's largest are listed as numerically zero instead of
    stretching the log axis. For each dataset the last ``max_annotations`` pivots below
    ``annotate_below`` mm (the markers best explained by the others) are labelled.
    """
    require_tables(tables, ("order", "marker", column), "r values")
    fig = Figure(figsize=(7.0, 4.6), layout="constrained")
    ax = fig.subplots()
    n_max = 1
    lows = []
    zeros: list[str] = []
    for d, (name, df) in enumerate(tables.items()):
        df = df.sort_values("order")
        order = df["order"].to_numpy(dtype=int)
        r = df[column].to_numpy(dtype=float)
        markers = df["marker"].astype(str).to_numpy()
        n_max = max(n_max, int(order.max()))
        c = colour(d)
        positive = r > NUMERICAL_ZERO * max(float(np.max(r)), 0.0)
        ax.plot(order, np.where(positive, r, np.nan), marker=MARKERS[d % len(MARKERS)], ms=3.5,
                lw=1.2, color=c, label=f"{name} ({len(order)} markers)")
        if (~positive).any():
            zeros.append(f"{name}: {', '.join(markers[~positive][:8])}"
                         + (" ..." if (~positive).sum() > 8 else ""))
        if positive.any():
            lows.append(float(r[positive].min()))
        below = np.flatnonzero((r < annotate_below) & positive)[-max_annotations:]
        for j, i in enumerate(below):
            ax.annotate(markers[i], (order[i], r[i]),
                        xytext=(-8 - 16 * (len(below) - 1 - j), -16 - 11 * d),
                        textcoords="offset points", fontsize=7.5, color=c, ha="center",
                        path_effects=HALO,
                        arrowprops={"arrowstyle": "-", "color": c, "lw": 0.6})
    ax.set_yscale("log")
    for t in sorted(tolerances):
        ax.axhline(t, color="0.35", ls="--", lw=0.8, zorder=0)
        ax.annotate(f"ε = {t:g} mm", (0.0, t), xycoords=("axes fraction", "data"),
                    xytext=(3, 2), textcoords="offset points", ha="left", va="bottom",
                    fontsize=7.5, color="0.3")
    if lows:
        ax.set_ylim(bottom=min(min(lows), min(tolerances, default=1.0)) / 2)
    if zeros:
        ax.text(0.99, 0.02, "numerically 0 (not on the log axis): " + "; ".join(zeros),
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7, color="0.3")
    ax.set_xlim(0.5, n_max + 0.5)
    ax.set_xlabel("pivot order (marker selected at step i of QR with column pivoting)")
    norms = {str(v) for df in tables.values() if "r_normalisation" in df.columns
             for v in df["r_normalisation"].unique()}
    ylabel = (_NORM_LABEL.get(norms.pop(), column) if len(norms) == 1
              else f"{column} (mm, log scale)")
    ax.set_ylabel(ylabel)
    ax.set_title("Independent motion of each pivot marker (diagonal of R)")
    ax.grid(True, which="major", alpha=0.3)
    plain_log_labels(ax.yaxis)
    ax.legend(fontsize=8, loc="upper right")
    return fig
