"""A designed marker set on the face: where to glue the k markers, and how well each of the
others is predicted (frontal view, :mod:`facemotion.plots.facemap` axes)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from facemotion.plots.facemap import HALO, MAIN_COLOUR, as_neutral, label_index, setup_frontal
from facemotion.plots.style import set_title


def plot_design(ms, title: str = "") -> Figure:
    """:func:`plot_marker_set` of a marker-set design
    (:class:`~facemotion.regions.design.MarkerSetDesign`): each predicted marker coloured by
    its expected held-out error, the head markers when the design has their reference."""
    err = ms.per_marker.set_index("marker").loc[ms.labels, "expected_error_mm"].to_numpy()
    return plot_marker_set(ms.neutral, ms.labels, ms.selected, err, ms.head_markers,
                           ms.head_reference, title=title)


def plot_marker_set(neutral, labels: Sequence[str], selected: Sequence[str], error_mm,
                    head: Sequence[str] = (), head_neutral=None, title: str = "") -> Figure:
    """The placed markers (red, numbered in selection order), the predicted ones coloured by
    their expected held-out error (mm), and the head markers (squares) when given."""
    neutral, labels = as_neutral(neutral, labels)
    err = np.asarray(error_mm, dtype=float)
    ip = label_index(labels, selected, "placed marker")
    pred = np.setdiff1d(np.arange(len(labels)), ip)
    fig = Figure(figsize=(7.5, 6.6), layout="constrained")
    ax = fig.subplots()
    xy = neutral[:, :2]
    norm = Normalize(0.0, max(float(np.nanmax(err[pred])) if pred.size else 1.0, 1e-9))
    sc = ax.scatter(xy[pred, 0], xy[pred, 1], s=28, c=err[pred], cmap="viridis", norm=norm,
                    linewidths=0, zorder=2)
    fig.colorbar(sc, ax=ax, shrink=0.8, label="expected held-out error (mm)")
    if head_neutral is not None and len(head):
        hn = np.asarray(head_neutral, dtype=float)
        ax.scatter(hn[:, 0], hn[:, 1], s=40, marker="s", facecolors="none",
                   edgecolors="0.3", zorder=2, label="head markers")
    ax.scatter(xy[ip, 0], xy[ip, 1], s=90, c=MAIN_COLOUR, edgecolors="white", linewidths=0.8,
               zorder=3, label="placed markers")
    setup_frontal(ax, xy if head_neutral is None else np.vstack([xy, hn[:, :2]]))
    for n, i in enumerate(ip, start=1):
        ax.annotate(f"{n}: {labels[i]}", xy[i], xytext=(4, 4), textcoords="offset points",
                    fontsize=8.5, color=MAIN_COLOUR, fontweight="bold", zorder=5,
                    path_effects=HALO)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(True, alpha=0.25)
    set_title(ax, title or f"{len(ip)} markers to place; the {pred.size} others predicted",
              fontsize=10)
    return fig
