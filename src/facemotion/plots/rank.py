"""Rank of the markers: r_rms of each pivot against its order (paper Fig. 2)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from facemotion.plots.facemap import HALO
from facemotion.plots.style import MARKERS, colour, plain_log_labels, require_tables


def plot_r_values(tables: Mapping[str, pd.DataFrame],
                  tolerances: Sequence[float] = (0.25, 0.5, 1.0),
                  annotate_below: float = 0.5, max_annotations: int = 3) -> Figure:
    """r_rms (mm) of the pivots against pivot order, datasets overlaid, log y axis.

    Dashed horizontal lines mark the epsilon tolerances; the epsilon-rank at a tolerance is the
    number of pivots above its line. For each dataset the last ``max_annotations`` pivots whose
    r_rms is below ``annotate_below`` mm (the markers best explained by the others) are
    labelled with their marker label.
    """
    require_tables(tables, ("order", "marker", "r_rms"), "r values")
    fig = Figure(figsize=(7.0, 4.6), layout="constrained")
    ax = fig.subplots()
    n_max = 1
    lows = []
    zeros: list[str] = []
    for d, (name, df) in enumerate(tables.items()):
        df = df.sort_values("order")
        order = df["order"].to_numpy(dtype=int)
        r = df["r_rms"].to_numpy(dtype=float)
        markers = df["marker"].astype(str).to_numpy()
        n_max = max(n_max, int(order.max()))
        c = colour(d)
        positive = r > 0
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
        ax.text(0.99, 0.02, "r_rms = 0 (not on the log axis): " + "; ".join(zeros),
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7, color="0.3")
    ax.set_xlim(0.5, n_max + 0.5)
    ax.set_xlabel("pivot order (marker selected at step i of QR with column pivoting)")
    ax.set_ylabel("r_rms of the pivot (mm, log scale)")
    ax.set_title("Independent motion of each pivot marker (diagonal of R)")
    ax.grid(True, which="major", alpha=0.3)
    plain_log_labels(ax.yaxis)
    ax.legend(fontsize=8, loc="upper right")
    return fig
