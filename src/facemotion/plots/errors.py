"""Held-out prediction error against k (paper Figs. 9-10) and a measured-vs-model trajectory."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator, PercentFormatter

from facemotion.errors import InputError
from facemotion.plots.style import MARKERS, colour, plain_log_labels, require_tables

_EXTRA = {"median_abs_error_mm": ("median", "--"), "rms_error_mm": ("rms", "-."),
          "max_abs_error_mm": ("max", ":")}


def plot_error_curves(df_by_dataset: Mapping[str, pd.DataFrame]) -> Figure:
    """Paper Fig. 10, two panels against k (number of main markers): left (Fig. 10 top) the
    held-out mean absolute error (mm; optional median / rms / max columns as thinner broken
    lines of the same colour), right (Fig. 10 bottom) the relative error averaged over markers
    (``rel_error_per_marker``, a fraction shown in %; the pooled ratio ``rel_error_pooled``, when
    present, as a thin dotted line). Datasets overlaid."""
    require_tables(df_by_dataset, ("k", "mean_abs_error_mm", "rel_error_per_marker"),
                   "error curves")
    fig = Figure(figsize=(10.0, 4.2), layout="constrained")
    ax_abs, ax_rel = fig.subplots(1, 2)
    extras_used = []
    zero_k: list[str] = []
    for d, (name, df) in enumerate(df_by_dataset.items()):
        df = df.sort_values("k")
        c, m = colour(d), MARKERS[d % len(MARKERS)]
        pos = df["mean_abs_error_mm"].where(df["mean_abs_error_mm"] > 0)  # log axis
        ax_abs.plot(df["k"], pos, color=c, marker=m, ms=3.5, lw=1.4, label=name)
        for col, (_, ls) in _EXTRA.items():
            if col in df.columns and df[col].notna().any():
                ax_abs.plot(df["k"], df[col].where(df[col] > 0), color=c, ls=ls, lw=0.9)
                if col not in extras_used:
                    extras_used.append(col)
        ax_rel.plot(df["k"], df["rel_error_per_marker"], color=c, marker=m, ms=3.5, lw=1.4,
                    label=name)
        if "rel_error_pooled" in df.columns:
            ax_rel.plot(df["k"], df["rel_error_pooled"], color=c, ls=":", lw=0.9)
        zk = df.loc[df["mean_abs_error_mm"] <= 0, "k"]
        if len(zk):
            zero_k.append(f"{name}: k = {', '.join(str(int(v)) for v in zk)}")
    ax_abs.set_yscale("log")
    if zero_k:
        ax_abs.text(0.02, 0.02, "zero error, not on the log axis: " + "; ".join(zero_k),
                    transform=ax_abs.transAxes, fontsize=7, color="0.3", va="bottom")
    ax_abs.set(xlabel="k (number of main markers)",
               ylabel="held-out 3-D error (mm, log scale)",
               title="Absolute error (paper Fig. 10 top)")
    plain_log_labels(ax_abs.yaxis)
    ax_rel.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    ax_rel.set_ylim(bottom=0)
    ax_rel.set(xlabel="k (number of main markers)",
               ylabel="relative error, mean over markers of\nmean |error| / mean |displacement|",
               title="Relative error (paper Fig. 10 bottom; dotted: pooled)")
    for ax in (ax_abs, ax_rel):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(True, which="major", alpha=0.3)
    handles, names = ax_abs.get_legend_handles_labels()
    style = [Line2D([], [], color="0.3", lw=1.4, label="mean")] if extras_used else []
    style += [Line2D([], [], color="0.3", lw=0.9, ls=_EXTRA[c][1], label=_EXTRA[c][0])
              for c in extras_used]
    ax_abs.legend(handles=handles + style, labels=names + [h.get_label() for h in style],
                  fontsize=8)
    ax_rel.legend(fontsize=8)
    fig.suptitle("Held-out prediction error of the secondary markers from k main markers")
    return fig


def plot_trajectory(time_s, measured, predicted, marker: str, sentence: str, k: int,
                    in_basis: bool = False, note: str | None = None) -> Figure:
    """Paper Fig. 9: x, y and z displacement (mm) of one marker over a held-out sentence,
    measured and predicted from the k main markers, three stacked panels sharing the time
    axis. ``in_basis``: the marker is one of the k main markers (the model copies it; the
    figure says so). ``note``: a further line under the title (e.g. why this marker)."""
    t = np.asarray(time_s, dtype=float)
    measured = np.asarray(measured, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    if measured.shape != (t.size, 3) or predicted.shape != (t.size, 3):
        raise InputError(f"trajectory of marker {marker}: measured {measured.shape} and "
                         f"predicted {predicted.shape} must both be ({t.size}, 3)")
    fig = Figure(figsize=(8.0, 6.4), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    names = ("x (talker's right → left)", "y (up)", "z (forward)")
    for a, ax in enumerate(axes):
        ax.plot(t, measured[:, a], color="black", lw=1.3, label="measured")
        ax.plot(t, predicted[:, a], color="#EE6677", lw=1.3, ls="--",
                label=f"model (k = {k} main markers)")
        err = np.nanmax(np.abs(measured[:, a] - predicted[:, a])) if t.size else np.nan
        ax.text(0.99, 0.04, f"max |error| {err:.2f} mm", transform=ax.transAxes, ha="right",
                va="bottom", fontsize=8, color="0.25")
        ax.set_ylabel(f"{names[a].split(' ')[0]} (mm)")
        ax.set_title(names[a], fontsize=9, loc="left")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right", ncols=2)
    axes[-1].set_xlabel("time (s)")
    title = (f"Marker {marker}, held-out sentence {sentence}, basis of {k} markers: "
             "displacement from neutral")
    if in_basis:
        title += (f"\nmarker {marker} is one of the {k} main markers: the model copies it, "
                  "so its error is zero")
    if note:
        title += f"\n({note})"
    fig.suptitle(title, color="#BB0000" if in_basis else "black")
    return fig
