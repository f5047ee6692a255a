"""Stability of the pivots against the number of sentences (paper Fig. 3)."""

from __future__ import annotations

import pandas as pd
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from matplotlib.transforms import offset_copy

from facemotion.errors import InputError
from facemotion.plots.style import (
    LINESTYLES,
    MARKERS,
    fixed_layout,
    plain_log_labels,
    require_columns,
    save_renderer,
    set_title,
    ticks_in_view,
    yaxis_width,
)


def _settle_labels(settling: pd.DataFrame | None, n_final: int) -> dict[int, str]:
    """Per pivot order: 'settles at n' or 'not within N' (censored) from the stability
    table."""
    if settling is None:
        return {}
    out = {}
    for _, r in settling.iterrows():
        ok = bool(r["settled"]) if "settled" in settling else r["settled_sentences"] < n_final
        out[int(r["order"])] = (f"settles at {int(r['settled_sentences'])}" if ok
                                else f"not within {n_final}")
    return out


def plot_sentence_sweep(df: pd.DataFrame, n_orders: int = 12,
                        settling: pd.DataFrame | None = None,
                        tolerance: float | None = None) -> Figure:
    """r_rms (mm) of the first ``n_orders`` pivots against the number of sentences used.

    One line per pivot order; the legend gives each order's marker label at the largest
    number of sentences (the marker may change at smaller numbers: its label there is marked
    on the line where it differs from the final one).  With the stability table ``settling``
    (``ranking.stability``), each order's settling point is circled and the legend says where
    it settles, or "not within N" when it only agrees with itself at the last n (censored).
    """
    require_columns(df, ("n_sentences", "order", "marker", "r_rms"), "sentence sweep")
    df = df[df["order"] <= n_orders].sort_values(["order", "n_sentences"])
    if df.empty:
        raise InputError(f"sentence sweep: no rows with order <= {n_orders}")
    orders = sorted(df["order"].unique())
    cmap = colormaps["viridis"]
    fig = Figure(figsize=(7.4, 4.8))
    ax = fig.subplots()
    n_final = int(df["n_sentences"].max())
    above = offset_copy(ax.transData, fig=fig, y=4, units="points")
    settle = _settle_labels(settling, n_final)
    for j, o in enumerate(orders):
        g = df[df["order"] == o]
        final = g[g["n_sentences"] == g["n_sentences"].max()]["marker"].astype(str).iloc[0]
        c = cmap(j / max(1, len(orders) - 1) * 0.9)
        ax.plot(g["n_sentences"], g["r_rms"], color=c, lw=1.3,
                ls=LINESTYLES[j % len(LINESTYLES)], marker=MARKERS[j % len(MARKERS)], ms=3.5,
                label=f"{int(o)}: {final}" + (f", {settle[int(o)]}" if int(o) in settle
                                               else ""))
        where = settle.get(int(o), "")
        if where.startswith("settles at "):
            n_s = int(where.rsplit(" ", 1)[1])
            at = g[g["n_sentences"] == n_s]["r_rms"]
            if len(at):
                ax.plot([n_s], [float(at.iloc[0])], marker="o", ms=9, mfc="none", mec=c,
                        mew=1.4, ls="")
        for n, m, r in zip(g["n_sentences"], g["marker"].astype(str), g["r_rms"], strict=True):
            if m != final:  # 4 points above the point; plain texts (an annotation measures
                # its point at every draw) left out of the layout, which they cannot change
                ax.text(n, r, m, transform=above, fontsize=6, color=c, ha="center",
                        in_layout=False)
    ax.set_xlabel("number of sentences in the displacement matrix")
    ns = sorted(int(n) for n in df["n_sentences"].unique())
    if len(ns) <= 12:  # whole numbers of sentences: tick each one
        ax.set_xticks(ns)
        ax.set_xlim(ns[0] - 0.5, ns[-1] + 0.5)
    else:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if len(ns) == 1:
        ax.text(0.5, 0.02, "one training sentence only: nothing to compare against",
                transform=ax.transAxes, ha="center", va="bottom", fontsize=8, color="0.3")
    if (df["r_rms"] > 0).all():
        ax.set_yscale("log")
        plain_log_labels(ax.yaxis)
        ax.set_ylabel("r_rms of the pivot (mm, log scale)")
    else:
        ax.set_ylabel("r_rms of the pivot (mm)")
    rule = ("" if settling is None else
            f"circle: settled (within {tolerance:.0%} of its value at n = {n_final} from then "
            "on)\n" if tolerance is not None else "circle: settled\n")
    set_title(ax, f"The first {len(orders)} pivots against the number of sentences\n"
                 f"{rule}(small labels: pivot marker where it differs from the final one)",
                 fontsize=9.5)
    ax.grid(True, alpha=0.3)
    w, h = fig.get_size_inches()
    pad = 0.04  # inches, as constrained layout's
    legend = fig.legend(title=f"order: marker\n(at n = {n_final})", fontsize=7.5,
                        title_fontsize=8, loc="upper right",
                        bbox_to_anchor=(1 - pad / w, 1 - pad / h))
    # fixed layout (inches): the legend's measured width (the marker labels vary) right of the
    # axes, the two-line title above, the measured y tick labels and label on the left
    legend_w = legend.get_window_extent(save_renderer(fig)).width / fig.dpi
    margins = {"right": legend_w + pad + 0.1, "bottom": 0.48,
               "top": 0.5 + (0.2 if settling is not None else 0.0)}
    fixed_layout(fig, left=0.6, **margins)
    fixed_layout(fig, left=yaxis_width(ax) + 0.05, **margins)
    ticks_in_view(ax)
    return fig
