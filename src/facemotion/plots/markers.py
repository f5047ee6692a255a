"""The marker layout: where each labelled marker sits on the face (frontal view)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from facemotion.plots.facemap import (
    HALO,
    MAIN_COLOUR,
    MARKER_COLOUR,
    as_neutral,
    label_index,
    setup_frontal,
)
from facemotion.plots.style import set_title


def plot_markers(neutral, labels: Sequence[str], highlight: Sequence[str] | None = None,
                 max_labels: int = 80) -> Figure:
    """Frontal (x, y) and profile (z, y) views of the neutral marker positions, labelled.

    Highlighted markers (e.g. the main markers) are drawn larger in red. With more than
    ``max_labels`` markers only the highlighted ones are labelled, and the title says so.
    """
    neutral, labels = as_neutral(neutral, labels)
    highlight = [str(h) for h in (highlight or [])]
    ih = label_index(labels, highlight, "highlighted marker") if highlight else np.array([], int)
    fig = Figure(figsize=(10.0, 6.4), layout="constrained")
    ax, side = fig.subplots(1, 2, width_ratios=[2.2, 1], sharey=True)
    xy = neutral[:, :2]
    ax.scatter(xy[:, 0], xy[:, 1], s=10, c=MARKER_COLOUR, linewidths=0, zorder=2)
    side.scatter(neutral[:, 2], neutral[:, 1], s=10, c=MARKER_COLOUR, linewidths=0, zorder=2)
    if ih.size:
        ax.scatter(xy[ih, 0], xy[ih, 1], s=45, c=MAIN_COLOUR, edgecolors="white",
                   linewidths=0.6, zorder=3, label="highlighted")
        side.scatter(neutral[ih, 2], neutral[ih, 1], s=45, c=MAIN_COLOUR, edgecolors="white",
                     linewidths=0.6, zorder=3)
        ax.legend(loc="lower right", fontsize=8)
    label_all = len(labels) <= max_labels
    to_label = range(len(labels)) if label_all else ih
    hs = set(ih.tolist())
    for i in to_label:
        ax.annotate(labels[i], xy[i], xytext=(2.5, 2.5), textcoords="offset points",
                    fontsize=7 if i not in hs else 8, zorder=4, path_effects=HALO,
                    color=MAIN_COLOUR if i in hs else "0.15",
                    fontweight="bold" if i in hs else "normal")
    setup_frontal(ax, xy)
    set_title(ax, "Frontal view (talker's right on the viewer's left)", fontsize=9.5)
    side.set_aspect("equal", adjustable="datalim")
    side.set_xlabel("z (mm), forward")
    set_title(side, "Profile from the talker's left (face to the right)", fontsize=9.5)
    for a in (ax, side):
        a.grid(True, alpha=0.25)
    note = "" if label_all else f"; labels shown for highlighted markers only ({len(labels)} " \
        "markers)"
    fig.suptitle(f"Marker layout at the neutral position: {len(labels)} markers{note}")
    return fig
