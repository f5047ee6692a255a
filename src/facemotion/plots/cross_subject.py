"""Figures that compare datasets and talkers: sweep summaries and selection agreement."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def plot_sweep_summary(table: pd.DataFrame, title: str = "sweep") -> Figure:
    """Three panels: epsilon-rank vs tolerance, held-out error vs k, settling vs sentences."""
    fig = Figure(figsize=(12, 3.8), layout="constrained")
    axes = fig.subplots(1, 3)
    for dataset, g in table.groupby("dataset", sort=True):
        t = g.groupby("tolerance_mm")["epsilon_rank"].mean()
        axes[0].plot(t.index, t.values, "o-", label=dataset)
        e = g.groupby("k")["heldout_mean_abs_error_mm"].mean()
        if e.notna().any():
            axes[1].plot(e.index, e.values, "o-", label=dataset)
        s = g.groupby("train_sentences")["heldout_mean_abs_error_mm"].mean()
        if s.notna().any() and len(s) > 1:
            axes[2].plot(s.index, s.values, "o-", label=dataset)
        else:
            st = g.groupby("train_sentences")["sentences_to_settle"].mean()
            axes[2].plot(st.index, st.values, "s--", label=f"{dataset} (settle)")
    axes[0].set(xlabel="epsilon tolerance (mm)", ylabel="epsilon-rank", title="rank")
    axes[1].set(xlabel="k (main markers)", ylabel="held-out mean abs. error (mm)",
                title="error vs k")
    axes[2].set(xlabel="training sentences", ylabel="held-out error (mm) / sentences to settle",
                title="training size")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
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
