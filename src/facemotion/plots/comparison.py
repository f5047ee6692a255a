"""The papers against this study: the key rows of ``paper_comparison.tsv`` as one figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from facemotion.plots.style import (
    fixed_layout,
    require_columns,
    save_renderer,
    set_title,
    ticks_in_view,
    yaxis_width,
)

VERDICT_COLOUR = {"reproduced": "#228833", "same shape": "#CCBB44", "differs": "#EE6677",
                  "not measured": "#BBBBBB"}
CLIP = (1e-2, 1e2)          # ratios beyond are drawn at the edge, their value written


def _number(s) -> float:
    try:
        return float(str(s))
    except ValueError:
        return np.nan


def numeric_rows(table: pd.DataFrame) -> pd.DataFrame:
    """Rows outside Table I (its cells and its counts against chance) whose paper and own
    values are both positive numbers, with ``ratio`` = ours / paper."""
    t = table[~table["where"].str.startswith("Table I")].copy()
    t["paper_num"] = t["paper_value"].map(_number)
    t["our_num"] = t["our_value"].map(_number)
    t = t[(t["paper_num"] > 0) & np.isfinite(t["our_num"]) & (t["our_num"] > 0)]
    t["ratio"] = t["our_num"] / t["paper_num"]
    return t


def plot_paper_comparison(table: pd.DataFrame) -> Figure:
    """Left: ours / paper for every numeric statement (log axis, 1.5x band; colour = verdict,
    hollow = not a prediction: a calibration target or a row by construction). Right: Table I's
    cells per dataset by verdict."""
    require_columns(table, ("where", "statement", "paper", "paper_value", "our_value",
                            "verdict", "class"), "paper comparison")
    num = numeric_rows(table)
    ti = table[table["where"] == "Table I"].copy()
    n = max(len(num), 1)
    fig = Figure(figsize=(12.0, 1.6 + 0.24 * n))
    ax, bx = fig.subplots(1, 2, width_ratios=[2.4, 1.0])
    _draw_ratios(ax, num)
    table_legend = _draw_table_i(bx, ti)
    set_title(bx, "L&M Table I cells: the same\nmarker (green) or not (red)",
                 fontsize=9)
    w, h = fig.get_size_inches()
    pad = 0.04  # inches from the figure's edges, as constrained layout's
    fig.suptitle("The papers' quantitative statements against this study "
                 "(tables/paper_comparison.tsv)", fontsize=11, y=1 - 0.08 / h, va="top")
    # fixed layout (inches): the suptitle and the right panel's two-line title above, the x
    # axes below and under them Table I's legend (its height measured), the statements (the
    # left panel's tick labels) and Table I's dataset names measured left of each panel
    renderer = save_renderer(fig)
    legend_w, legend_h = ((table_legend.get_window_extent(renderer).size / fig.dpi)
                          if table_legend is not None else (0.0, 0.0))
    margins = {"right": 0.15, "top": 0.7, "bottom": 0.5 + (legend_h + 0.12 if legend_h else 0)}
    fixed_layout(fig, left=4.0, wgap=0.6, **margins)
    fixed_layout(fig, left=yaxis_width(ax) + pad,
                 wgap=(yaxis_width(bx) if bx.axison else 0.0) + 0.25, **margins)
    ticks_in_view(ax, bx)
    if table_legend is not None:  # under the x axis, centred on the panel, inside the figure
        box = bx.get_position()
        x = min((box.x0 + box.x1) / 2, 1 - (pad + legend_w / 2) / w)
        table_legend.set_bbox_to_anchor((x, pad / h), transform=fig.transFigure)
    return fig


def _draw_ratios(ax, num: pd.DataFrame) -> None:
    """Left panel: ours / paper of each numeric statement, one row each, on a log axis."""
    y = np.arange(len(num))[::-1]
    ax.axvspan(1 / 1.5, 1.5, color="0.9", zorder=0)
    ax.axvline(1.0, color="0.5", lw=0.8, zorder=1)
    for yi, (_, r) in zip(y, num.iterrows(), strict=True):
        c = VERDICT_COLOUR[r["verdict"]]
        x = float(np.clip(r["ratio"], *CLIP))
        cal = r["class"] != "prediction"
        ax.plot([x], [yi], marker="o", ms=7, mec=c, mfc="white" if cal else c, mew=1.8,
                zorder=3)
        if x != r["ratio"]:
            ax.annotate(f"{r['ratio']:.2g}", (x, yi), xytext=(-6 if x > 1 else 6, 4),
                        textcoords="offset points", fontsize=7,
                        ha="right" if x > 1 else "left", color="0.25")
    short = {"Lucero & Munhall 2008": "L&M", "Basu & Pentland 1997": "B&P"}
    labels = [f"{short.get(r['paper'], r['paper'])} {r['where']}: {r['statement']}"
              for _, r in num.iterrows()]
    ax.set_yticks(y, labels, fontsize=7.5)
    ax.set_xscale("log")
    ax.set_xlim(CLIP[0] / 1.5, CLIP[1] * 1.5)
    ax.set_ylim(-0.8, max(len(num) - 0.2, 0.8))
    ax.set_xlabel("our value / the paper's value (log scale; grey band: within 1.5x)")
    set_title(ax, "Numeric statements of the papers", fontsize=10)
    ax.grid(True, axis="x", which="major", alpha=0.3)
    handles = [Line2D([], [], ls="", marker="o", mfc=c, mec=c, label=v)
               for v, c in VERDICT_COLOUR.items() if v != "not measured"]
    handles.append(Line2D([], [], ls="", marker="o", mfc="white", mec="0.3",
                          label="calibration or by construction"))
    ax.legend(handles=handles, fontsize=7.5, loc="lower right")


def _draw_table_i(bx, ti: pd.DataFrame):
    """Right panel: Table I's cells per dataset by verdict; its legend (None without cells)."""
    if not len(ti):
        bx.text(0.5, 0.5, "Table I not measured", ha="center", va="center",
                transform=bx.transAxes)
        bx.set_axis_off()
        return None
    ti["dataset"] = ti["statement"].str.split(",").str[0]
    order = list(dict.fromkeys(ti["dataset"]))
    counts = ti.groupby(["dataset", "verdict"]).size().unstack(fill_value=0)
    left = np.zeros(len(order))
    for v, c in VERDICT_COLOUR.items():
        vals = np.array([counts.loc[d, v] if v in counts.columns else 0 for d in order],
                        float)
        bx.barh(np.arange(len(order))[::-1], vals, left=left, color=c, label=v)
        for i, (lv, vv) in enumerate(zip(left, vals, strict=True)):
            if vv:
                bx.text(lv + vv / 2, len(order) - 1 - i, str(int(vv)), ha="center",
                        va="center", fontsize=8)
        left += vals
    bx.set_yticks(np.arange(len(order))[::-1], order)
    bx.set_xlabel("cells (first 16 pivots)")
    bx.set_xlim(0, max(left.max(), 1))
    return bx.legend(fontsize=7.5, loc="lower center", ncols=2)
