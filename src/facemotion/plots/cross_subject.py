"""Figures that compare datasets and talkers: sweep summaries and selection agreement."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from facemotion.errors import InputError
from facemotion.plots.style import LINESTYLES, MARKERS, colour

#: the sweep's axes (columns of the summary table): numeric ones can be an x axis
NUMERIC_AXES = {"tolerance_mm": "epsilon tolerance (mm)", "k": "k (number of main markers)",
                "train_sentences": "training sentences"}
CATEGORICAL_AXES = ("dataset", "marker_subset")
#: quantity -> (axis label, the axes it depends on, integer-valued)
QUANTITIES = {
    "epsilon_rank": ("epsilon-rank", ("dataset", "marker_subset", "tolerance_mm",
                                      "train_sentences"), True),
    "heldout_mean_abs_error_mm": ("held-out mean |error| (mm)",
                                  ("dataset", "marker_subset", "k", "train_sentences"), False),
    "sentences_to_settle": ("sentences for the first pivots to settle",
                            ("dataset", "marker_subset", "train_sentences"), True),
}


def _series_label(key: dict, n_markers: dict) -> str:
    parts = []
    for a, v in key.items():
        if a == "dataset":
            parts.append(str(v))
        elif a == "marker_subset":
            n = n_markers.get(v)
            parts.append(f"{v} ({n} markers)" if n is not None else str(v))
        elif a == "tolerance_mm":
            parts.append(f"ε = {v:g} mm")
        elif a == "train_sentences":
            parts.append(f"{int(v)} training sentence{'s' if int(v) != 1 else ''}")
        else:
            parts.append(f"{a} = {v:g}" if isinstance(v, float) else f"{a} = {v}")
    return ", ".join(parts) or "all points"


def _panels(table: pd.DataFrame) -> list[dict]:
    """One panel per (quantity, numeric axis it depends on that the sweep varies); a quantity
    that depends on no varied numeric axis gets one panel with a point per series.

    Rows are never averaged: points that differ only in axes the quantity does not depend on
    must agree (they are then drawn once); if they do not, those axes stay in the series key.
    """
    axes = [a for a in (*CATEGORICAL_AXES, *NUMERIC_AXES) if a in table.columns]
    varying = [a for a in axes if table[a].nunique(dropna=False) > 1]
    panels = []
    for q, (ylabel, deps, integer) in QUANTITIES.items():
        if q not in table.columns:
            continue
        t = table[np.isfinite(pd.to_numeric(table[q], errors="coerce"))]
        if t.empty:
            continue
        relevant = [a for a in varying if a in deps]
        agree = (t.groupby(relevant, dropna=False)[q].nunique() <= 1).all() if relevant \
            else t[q].nunique() <= 1
        if not agree:
            relevant = list(varying)
        t = t.drop_duplicates(relevant) if relevant else t.iloc[:1]
        xs = [a for a in relevant if a in NUMERIC_AXES]
        if not xs:
            panels.append({"q": q, "ylabel": ylabel, "integer": integer, "x": None,
                           "series": relevant, "data": t})
        for x in xs:
            panels.append({"q": q, "ylabel": ylabel, "integer": integer, "x": x,
                           "series": [a for a in relevant if a != x], "data": t})
    return panels


def plot_sweep_summary(table: pd.DataFrame, title: str = "sweep") -> Figure:
    """Each swept quantity (epsilon-rank, held-out error at k, sentences to settle) against
    each swept setting it depends on; one line per combination of the other swept axes
    (dataset, marker subset, ...) with a legend naming it. Nothing is averaged over points.
    Settings the sweep does not vary are listed under the title."""
    if "dataset" not in table.columns or table.empty:
        raise InputError("sweep summary: empty table or no 'dataset' column")
    panels = _panels(table)
    if not panels:
        raise InputError(f"sweep summary: none of {list(QUANTITIES)} has a finite value")
    n_markers = {}
    if {"marker_subset", "n_markers"} <= set(table.columns):
        n_markers = {s: int(g["n_markers"].iloc[0]) for s, g in table.groupby("marker_subset")
                     if g["n_markers"].nunique() == 1}
    ncols = min(3, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    fig = Figure(figsize=(4.3 * ncols + 0.4, 3.9 * nrows + 0.6), layout="constrained")
    axs = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    identities: dict[tuple, int] = {}
    for ax, p in zip(axs, panels, strict=False):
        t, q, x, series = p["data"], p["q"], p["x"], p["series"]
        groups = list(t.groupby(series, sort=True, dropna=False)) if series else [((), t)]
        if x is None:
            labels = []
            for j, (key, g) in enumerate(groups):
                key = dict(zip(series, key if isinstance(key, tuple) else (key,), strict=True))
                labels.append(_series_label(key, n_markers))
                ci = identities.setdefault(tuple(key.get(a) for a in CATEGORICAL_AXES),
                                           len(identities))
                v = float(g[q].iloc[0])
                ax.plot([j], [v], ls="none", marker="o", ms=6, color=colour(ci))
                ax.annotate(f"{v:g}" if p["integer"] else f"{v:.3g}", (j, v),
                            xytext=(7, 0), textcoords="offset points", va="center",
                            fontsize=8, color=colour(ci))
            ax.set_xticks(np.arange(len(labels)), labels, rotation=20, ha="right", fontsize=8)
            ax.set_xlim(-0.6, len(labels) - 0.4)
            ax.margins(y=0.15)
            ax.set_xlabel(" / ".join(a.replace("_", " ") for a in series))
        else:
            keys = [dict(zip(series, k if isinstance(k, tuple) else (k,), strict=True))
                    for k, _ in groups]
            rests = sorted({tuple(v for a, v in key.items() if a not in CATEGORICAL_AXES)
                            for key in keys})
            for key, (_, g) in zip(keys, groups, strict=True):
                ident = tuple(key.get(a) for a in CATEGORICAL_AXES)
                ci = identities.setdefault(ident, len(identities))
                si = rests.index(tuple(v for a, v in key.items() if a not in CATEGORICAL_AXES))
                g = g.sort_values(x)
                ax.plot(g[x].to_numpy(dtype=float), g[q].to_numpy(dtype=float), color=colour(ci),
                        ls=LINESTYLES[si % len(LINESTYLES)], marker=MARKERS[si % len(MARKERS)],
                        ms=4.5, lw=1.4, label=_series_label(key, n_markers))
            ax.set_xlabel(NUMERIC_AXES[x])
            values = np.sort(t[x].unique().astype(float))
            ax.set_xticks(values, [f"{v:g}" for v in values])
            if len(groups) > 4:
                ax.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0))
            elif series:
                ax.legend(fontsize=7.5, loc="best")
        ax.set_ylabel(p["ylabel"])
        if p["integer"]:  # counts: from 0, so that 16 against 28 looks like it
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
    for ax in axs[len(panels):]:
        ax.set_axis_off()
    fixed = []
    for a in (*CATEGORICAL_AXES, *NUMERIC_AXES):
        if a in table.columns and table[a].nunique(dropna=False) == 1:
            name = {"dataset": "dataset", "marker_subset": "markers"}.get(a, "")
            fixed.append(f"{name} {_series_label({a: table[a].iloc[0]}, n_markers)}".strip())
    sub = f"\nthe same at every point: {'; '.join(fixed)}" if fixed else ""
    fig.suptitle(f"{title}: one line per combination of the other swept settings{sub}",
                 fontsize=10.5)
    return fig


def plot_talkers(table: pd.DataFrame, freq: pd.DataFrame, top: int = 20) -> Figure:
    """How often each marker is among the first 10 pivots across talkers, and the ranks of
    the lower lip, the jaw and the lip corners."""
    fig = Figure(figsize=(12, 4.2), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2, width_ratios=[1.6, 1])
    f = freq.head(top)
    ax1.bar(np.arange(len(f)), f["fraction"], color="#4477aa")
    ax1.set_xticks(np.arange(len(f)), f["marker"], rotation=90)
    ax1.set(xlabel="marker", ylabel="fraction of talkers",
            title=f"among the first 10 pivots ({len(table)} talkers)", ylim=(0, 1.05))
    cols = [c for c in table.columns if c.startswith("rank_")]
    data = [table[c].to_numpy() for c in cols]
    ax2.boxplot(data, vert=True)
    ax2.set_xticks(np.arange(1, len(cols) + 1), [c.removeprefix("rank_") for c in cols],
                   rotation=30)
    ax2.set(ylabel="pivot order", title="where named markers rank")
    ax2.invert_yaxis()
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3, axis="y")
    return fig
