"""Held-out prediction error against k (paper Fig. 10) and a marker's trajectory (Fig. 9)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator, PercentFormatter

from facemotion.errors import InputError
from facemotion.plots.style import (
    MARKERS,
    colour,
    fixed_layout,
    plain_log_labels,
    require_tables,
    set_title,
    ticks_in_view,
    yaxis_width,
)

_EXTRA = {"median_abs_error_mm": ("median", "--"), "rms_error_mm": ("RMS", "-."),
          "max_abs_error_mm": ("max", ":")}
#: Each column's factor to a 3-D distance: rms_error_mm is an RMS per coordinate, and the RMS
#: 3-D distance is sqrt(3) times it (the axis shows 3-D distances).
_TO_3D = {"rms_error_mm": np.sqrt(3.0)}


def without_all_main(df: pd.DataFrame, n_markers: int | None = None
                     ) -> tuple[pd.DataFrame, int | None]:
    """The curve without its k = n row (every marker main: no secondary marker is left, so
    the error is undefined, not 0). With ``n_markers`` given, rows with k >= n are dropped;
    otherwise the table's own contract (``prediction.error_curve`` appends k = n with all
    errors exactly 0) identifies it: the largest k, if all its error columns are 0.
    Returns the rows kept and the n dropped (None if nothing was dropped)."""
    df = df.sort_values("k")
    if n_markers is not None:
        keep = df["k"] < int(n_markers)
        return df[keep], (int(n_markers) if (~keep).any() else None)
    if df.empty:
        return df, None
    last = df.iloc[-1]
    cols = [c for c in ("mean_abs_error_mm", "rel_error_per_marker", *_EXTRA,
                        "rel_error_pooled") if c in df.columns]
    if all(float(last[c]) == 0.0 for c in cols):
        return df.iloc[:-1], int(last["k"])
    return df, None


def plot_error_curves(df_by_dataset: Mapping[str, pd.DataFrame],
                      n_markers: Mapping[str, int] | None = None) -> Figure:
    """Paper Fig. 10, two panels against k (number of main markers): left (Fig. 10 top) the
    held-out mean absolute 3-D error (mm; optional median / RMS / max 3-D distances as thinner
    broken lines of the same colour; the table's per-coordinate RMS times sqrt(3)), right
    (Fig. 10 bottom) the relative error averaged over markers
    (``rel_error_per_marker``, a fraction shown in %; the pooled ratio ``rel_error_pooled``, when
    present, as a thin dotted line). Datasets overlaid.

    k = n (no secondary marker left) is not drawn (see :func:`without_all_main`); notes under
    the panels say so, and list any k < n with (numerically) zero error: below 1e-9 of the
    largest, e.g. an exactly copied marker, not drawn on the log axis.
    """
    require_tables(df_by_dataset, ("k", "mean_abs_error_mm", "rel_error_per_marker"),
                   "error curves")
    fig = Figure(figsize=(10.0, 4.4))
    ax_abs, ax_rel = fig.subplots(1, 2)
    drawn = _draw_curves(ax_abs, ax_rel, df_by_dataset, n_markers)
    ax_abs.set_yscale("log")
    notes = []
    if drawn.all_main:
        notes.append("k = n not drawn (every marker is main, none is left to predict: the "
                     "error is undefined): " + "; ".join(
                         f"n = {n} ({', '.join(names)})" for n, names in drawn.all_main.items()))
    if drawn.zero_k:
        notes.append("(numerically) zero error, not on the log axis: " + "; ".join(drawn.zero_k))
    note_lines = sum(n.count("\n") + 1 for n in notes)
    if notes:
        fig.supxlabel("\n".join(notes), fontsize=7.5, color="0.3")
    _label_panels(ax_abs, ax_rel)
    _legends(ax_abs, ax_rel, drawn.extras_used, drawn.pooled)
    fig.suptitle("Held-out prediction error of the secondary markers from k main markers")
    # fixed layout (inches): the titles above, the notes under the panels (0.15 in a line),
    # the y axes' measured tick labels and labels left of each panel
    margins = {"right": 0.12, "top": 0.52,
               "bottom": 0.48 + (0.05 + 0.15 * note_lines if note_lines else 0.0)}
    fixed_layout(fig, left=0.6, wgap=0.96, **margins)
    fixed_layout(fig, left=yaxis_width(ax_abs) + 0.05, wgap=yaxis_width(ax_rel) + 0.2,
                 **margins)
    ticks_in_view(ax_abs, ax_rel)
    return fig


@dataclass
class _Drawn:
    """What the curves drawn leave for the notes and legends."""

    extras_used: list[str] = field(default_factory=list)
    zero_k: list[str] = field(default_factory=list)
    all_main: dict[int, list[str]] = field(default_factory=dict)
    pooled: bool = False


def _draw_curves(ax_abs, ax_rel, df_by_dataset: Mapping[str, pd.DataFrame],
                 n_markers: Mapping[str, int] | None) -> _Drawn:
    """Each dataset's absolute (left) and relative (right) error against k."""
    drawn = _Drawn()
    for d, (name, df) in enumerate(df_by_dataset.items()):
        df, n_dropped = without_all_main(df, (n_markers or {}).get(name))
        if n_dropped is not None:
            drawn.all_main.setdefault(n_dropped, []).append(str(name))
        c, m = colour(d), MARKERS[d % len(MARKERS)]
        # log axis: an error below 1e-9 of the largest is numerically zero (an exact copy)
        tiny = 1e-9 * float(df["mean_abs_error_mm"].max()) if len(df) else 0.0
        pos = df["mean_abs_error_mm"].where(df["mean_abs_error_mm"] > tiny)
        ax_abs.plot(df["k"], pos, color=c, marker=m, ms=3.5, lw=1.4, label=name)
        for col, (_, ls) in _EXTRA.items():
            if col in df.columns and df[col].notna().any():
                v = df[col] * _TO_3D.get(col, 1.0)
                ax_abs.plot(df["k"], v.where(v > 1e-9 * v.max()), color=c, ls=ls, lw=0.9)
                if col not in drawn.extras_used:
                    drawn.extras_used.append(col)
        ax_rel.plot(df["k"], df["rel_error_per_marker"], color=c, marker=m, ms=3.5, lw=1.4,
                    label=name)
        if "rel_error_pooled" in df.columns:
            ax_rel.plot(df["k"], df["rel_error_pooled"], color=c, ls=":", lw=0.9)
            drawn.pooled = True
        zk = df.loc[df["mean_abs_error_mm"] <= tiny, "k"]
        if len(zk):
            drawn.zero_k.append(f"{name}: k = {', '.join(str(int(v)) for v in zk)}")
    return drawn


def _label_panels(ax_abs, ax_rel) -> None:
    """Axis labels, titles, the relative error in %, integer k, grids."""
    ax_abs.set(xlabel="k (number of main markers)",
               ylabel="held-out 3-D error (mm, log scale)")
    set_title(ax_abs, "Absolute error (paper Fig. 10 top)")
    plain_log_labels(ax_abs.yaxis)
    ax_rel.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    ax_rel.set_ylim(bottom=0)
    ax_rel.set(xlabel="k (number of main markers)",
               ylabel="relative error, mean over markers of\nmean |error| / mean |displacement|")
    set_title(ax_rel, "Relative error (paper Fig. 10 bottom)")
    for ax in (ax_abs, ax_rel):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(True, which="major", alpha=0.3)


def _legends(ax_abs, ax_rel, extras_used: list[str], pooled: bool) -> None:
    """The datasets, with the line styles of the extra statistics and the pooled ratio."""
    handles, names = ax_abs.get_legend_handles_labels()
    style = [Line2D([], [], color="0.3", lw=1.4, label="mean")] if extras_used else []
    style += [Line2D([], [], color="0.3", lw=0.9, ls=_EXTRA[c][1], label=_EXTRA[c][0])
              for c in extras_used]
    ax_abs.legend(handles=handles + style, labels=names + [h.get_label() for h in style],
                  fontsize=8)
    handles, names = ax_rel.get_legend_handles_labels()
    if pooled:
        handles.append(Line2D([], [], color="0.3", lw=0.9, ls=":"))
        names.append("pooled: sum |error| / sum |displacement|")
    ax_rel.legend(handles=handles, labels=names, fontsize=8)


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
    fig = Figure(figsize=(8.0, 6.4))
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
        set_title(ax, names[a], fontsize=9, loc="left")
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
    # fixed layout (inches): the suptitle's lines (0.2 in each) 0.08 in under the top edge,
    # each panel's title between the panels, the measured y tick labels and labels on the left
    fig.suptitle(title, color="#BB0000" if in_basis else "black",
                 y=1 - 0.08 / fig.get_figheight(), va="top")
    margins = {"right": 0.12, "bottom": 0.48, "hgap": 0.32,
               "top": 0.52 + 0.2 * title.count("\n")}
    fixed_layout(fig, left=0.6, **margins)
    fixed_layout(fig, left=yaxis_width(*axes) + 0.05, **margins)
    ticks_in_view(*axes)
    return fig
