"""Agreement of the marker selections across datasets or talkers (paper Table I)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.colors import BoundaryNorm
from matplotlib.figure import Figure

from facemotion.errors import InputError
from facemotion.plots.style import set_title


def selection_counts(table: pd.DataFrame, k: int) -> pd.DataFrame:
    """Per marker: in how many datasets it is among the first k pivots, and its orders.

    table: column ``order`` (1..) and one column of marker labels per dataset. Returns columns
    ``marker, count`` plus one order column per dataset (NaN where not among the first k),
    sorted by count (descending), then mean order, then label.
    """
    if "order" not in table.columns:
        raise InputError("selection table lacks column 'order'")
    datasets = [c for c in table.columns if c != "order"]
    if not datasets:
        raise InputError("selection table has no dataset columns")
    if k < 1:
        raise InputError(f"selection agreement: k must be at least 1, got {k}")
    top = table[table["order"] <= k]
    rows: dict[str, dict[str, float]] = {}
    for d in datasets:
        for o, m in zip(top["order"], top[d], strict=True):
            if pd.isna(m) or str(m) == "":
                continue
            rows.setdefault(str(m), {})[d] = float(o)
    out = pd.DataFrame([{"marker": m, **v} for m, v in rows.items()],
                       columns=["marker", *datasets])
    out["count"] = out[datasets].notna().sum(axis=1).astype(int)
    out["_mean"] = out[datasets].mean(axis=1)
    out = out.sort_values(["count", "_mean", "marker"], ascending=[False, True, True])
    return out.drop(columns="_mean")[["marker", "count", *datasets]].reset_index(drop=True)


def plot_selection_agreement(table: pd.DataFrame, k: int | None = None) -> Figure:
    """Heat map of the pivot order of every marker selected among the first k in any dataset
    (rows: markers, most often selected first; columns: datasets; the order is written in the
    cell), beside a bar of how many datasets select each marker among their first k."""
    if k is None:
        k = int(table["order"].max()) if "order" in table.columns and len(table) else 0
    counts = selection_counts(table, k)
    datasets = [c for c in counts.columns if c not in ("marker", "count")]
    nm = len(counts)
    fig = Figure(figsize=(3.0 + 0.75 * len(datasets), 1.6 + 0.24 * max(nm, 4)),
                 layout="constrained")
    ax, bar = fig.subplots(1, 2, sharey=True, width_ratios=[max(len(datasets), 1), 2.2])
    M = counts[datasets].to_numpy(dtype=float)
    cmap = colormaps["viridis"].with_extremes(bad="white")
    norm = BoundaryNorm(np.arange(0.5, k + 1.5), cmap.N)
    im = ax.imshow(np.ma.masked_invalid(M), cmap=cmap, norm=norm, aspect="auto",
                   interpolation="nearest")
    for i in range(nm):
        for j in range(len(datasets)):
            if np.isfinite(M[i, j]):
                v = M[i, j]
                ax.text(j, i, f"{int(v)}", ha="center", va="center", fontsize=7,
                        color="white" if v < 0.55 * k else "black")
    ax.set_xticks(np.arange(len(datasets)), datasets, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(np.arange(nm), counts["marker"], fontsize=7.5)
    ax.set_xlabel("dataset")
    ax.set_ylabel("marker")
    set_title(ax, f"Pivot order (blank: not among first {k})", fontsize=9)
    cb = fig.colorbar(im, ax=ax, location="bottom", shrink=0.9, aspect=30)
    cb.set_ticks(np.arange(1, k + 1, max(1, k // 8)))
    cb.set_label("pivot order")
    bar.barh(np.arange(nm), counts["count"], color="#4477AA", height=0.7)
    bar.set_xlim(0, len(datasets) + 0.3)
    bar.set_xlabel("datasets selecting it")
    set_title(bar, f"among the first {k}", fontsize=9)
    bar.grid(True, axis="x", alpha=0.3)
    bar.xaxis.get_major_locator().set_params(integer=True)
    fig.suptitle(f"Agreement of the first {k} selected markers across {len(datasets)} datasets")
    return fig
