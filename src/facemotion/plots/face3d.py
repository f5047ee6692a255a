"""An interactive 3-D page of a study: each dataset's markers at rest, coloured by the kinematic
region they belong to (the main marker that predicts them most, Lucero & Munhall 2008, Sec.
II.D), the designed marker set highlighted, and per marker a hover card (label, pivot order,
region, expected held-out error).  One self-contained HTML file (plotly.js inline, no server);
a menu switches between datasets.  Needs plotly (the 'plotly' extra)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from facemotion.errors import InputError

#: Paul Tol's "muted" qualitative scheme (colour-blind safe), cycled over the regions.
REGION_COLOURS = ["#CC6677", "#332288", "#DDCC77", "#117733", "#88CCEE", "#882255",
                  "#44AA99", "#999933", "#AA4499", "#6699CC"]
SELECTED_COLOUR = "#000000"
#: The page's plot element id: fixed, so that the page is the same bytes on every rerun.
DIV_ID = "facemotion-face-3d"


@dataclass
class FaceView:
    """One dataset on the page: ``neutral`` (n, 3) mm; ``region`` the main marker of each
    marker's region; ``order`` each marker's pivot order (1 = first); ``error_mm`` its
    expected held-out error with ``error_low_mm``/``error_high_mm`` (NaN when unknown);
    ``selected`` the designed set."""

    name: str
    labels: list[str]
    neutral: np.ndarray
    region: list[str]
    order: list[int]
    selected: list[str]
    error_mm: np.ndarray = field(default_factory=lambda: np.empty(0))
    error_low_mm: np.ndarray = field(default_factory=lambda: np.empty(0))
    error_high_mm: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        n = len(self.labels)
        self.neutral = np.asarray(self.neutral, dtype=float)
        if self.neutral.shape != (n, 3) or len(self.region) != n or len(self.order) != n:
            raise InputError(f"{self.name}: {n} labels but neutral {self.neutral.shape}, "
                             f"{len(self.region)} regions, {len(self.order)} pivot orders")
        for a in ("error_mm", "error_low_mm", "error_high_mm"):
            v = np.asarray(getattr(self, a), dtype=float)
            setattr(self, a, v if v.size else np.full(n, np.nan))
        unknown = [m for m in self.selected if m not in self.labels]
        if unknown:
            raise InputError(f"{self.name}: selected marker(s) {unknown} not among its labels")


def regions_from_coefficients(labels: Sequence[str], coef: Mapping[str, Mapping[str, float]]
                              ) -> list[str]:
    """Each marker's region: itself for a main marker, else the main marker with the largest
    |X| coefficient in its column (``coef[main][secondary]``, X = R11^-1 R12)."""
    mains = list(coef)
    out = []
    for m in labels:
        if m in coef:
            out.append(m)
            continue
        weights = [abs(float(coef[k].get(m, 0.0))) for k in mains]
        out.append(mains[int(np.argmax(weights))] if weights else m)
    return out


def _hover(v: FaceView, j: int) -> str:
    m = v.labels[j]
    if m in v.selected:
        err = "placed (measured)"
    elif math.isfinite(v.error_mm[j]):
        err = (f"{v.error_mm[j]:.2f} mm ({v.error_low_mm[j]:.2f}-{v.error_high_mm[j]:.2f})")
    else:
        err = "not evaluated"
    return (f"<b>{m}</b><br>pivot order: {v.order[j]}<br>region of: {v.region[j]}"
            f"<br>held-out error: {err}")


def _traces(v: FaceView, visible: bool) -> list[dict]:
    mains = list(dict.fromkeys(v.region))
    colour = {r: REGION_COLOURS[i % len(REGION_COLOURS)] for i, r in enumerate(mains)}
    x, y, z = (np.round(v.neutral[:, i], 4).tolist() for i in range(3))
    cloud = dict(type="scatter3d", mode="markers", name=f"{v.name}: markers", x=x, y=y, z=z,
                 visible=visible, marker=dict(size=6, color=[colour[r] for r in v.region]),
                 hovertext=[_hover(v, j) for j in range(len(v.labels))],
                 hovertemplate="%{hovertext}<extra></extra>")
    idx = [v.labels.index(m) for m in v.selected]
    chosen = dict(type="scatter3d", mode="markers+text", name=f"{v.name}: selected set",
                  x=[x[j] for j in idx], y=[y[j] for j in idx], z=[z[j] for j in idx],
                  visible=visible, text=list(v.selected), textposition="top center",
                  marker=dict(size=11, color="rgba(0,0,0,0)",
                              line=dict(color=SELECTED_COLOUR, width=3)),
                  hovertext=[_hover(v, j) for j in idx],
                  hovertemplate="%{hovertext}<extra></extra>")
    return [cloud, chosen]


def face_page(views: Sequence[FaceView], title: str) -> str:
    """The page's HTML (the same text for the same views)."""
    import plotly.graph_objects as go

    if not views:
        raise InputError("face page: no dataset to show")
    traces = []
    for i, v in enumerate(views):
        traces += _traces(v, i == 0)
    buttons = []
    for i, v in enumerate(views):
        vis = [j // 2 == i for j in range(len(traces))]
        buttons.append(dict(label=v.name, method="update",
                            args=[{"visible": vis}, {"title.text": f"{title}: {v.name}"}]))
    fig = go.Figure(data=traces)
    fig.update_layout(
        title=dict(text=f"{title}: {views[0].name}", x=0.12), height=760, showlegend=True,
        scene=dict(aspectmode="data", xaxis_title="x (mm)", yaxis_title="y (mm)",
                   zaxis_title="z (mm)", camera=dict(eye=dict(x=0, y=0, z=2.2),
                                                     up=dict(x=0, y=1, z=0))),
        updatemenus=[dict(buttons=buttons, direction="down", x=0.0, y=1.08,
                          xanchor="left", showactive=True)],
        margin=dict(l=0, r=0, t=80, b=0))
    return fig.to_html(include_plotlyjs=True, full_html=True, div_id=DIV_ID,
                       config={"displaylogo": False, "responsive": True})
