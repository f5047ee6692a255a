"""Figures of the lip model: the mesh (tracked and fixed nodes marked) and its learned modes
(Basu & Pentland 1997, Fig. 9: the mean displacement and some characteristic modes).

Matplotlib `Figure` objects built without pyplot's global state; deterministic.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from facemotion.lips.mesh import LipMesh
from facemotion.plots.style import set_title

_VIEWS = (("frontal (x-y)", 0, 1), ("profile (z-y)", 2, 1))


def _draw(ax, mesh: LipMesh, nodes: np.ndarray, a: int, b: int, color: str = "0.5",
          lw: float = 0.5) -> None:
    tri = mesh.triangles
    edges = np.unique(np.sort(np.stack([tri, np.roll(tri, -1, axis=1)], axis=2).reshape(-1, 2),
                              axis=1), axis=0)
    ax.add_collection(LineCollection(nodes[edges][:, :, [a, b]], colors=color, linewidths=lw))
    ax.autoscale_view()


def plot_mesh(mesh: LipMesh, tracked: list[str] | np.ndarray | None = None,
              fixed: np.ndarray | None = None) -> Figure:
    """Two orthographic views of the mesh; tracked points red dots, fixed nodes black x."""
    tr = (mesh.indices(list(tracked)) if tracked is not None and len(tracked)
          and isinstance(list(tracked)[0], str) else np.asarray(
              tracked if tracked is not None else [], dtype=int))
    fx = mesh.fixed if fixed is None else np.asarray(fixed, dtype=int)
    fig = Figure(figsize=(10, 4.5))
    for i, (title, a, b) in enumerate(_VIEWS):
        ax = fig.add_subplot(1, 2, i + 1)
        _draw(ax, mesh, mesh.nodes, a, b)
        ax.plot(mesh.nodes[fx, a], mesh.nodes[fx, b], "kx", ms=4, label="fixed")
        if len(tr):
            ax.plot(mesh.nodes[tr, a], mesh.nodes[tr, b], "o", color="tab:red", ms=5,
                    label="tracked")
        set_title(ax, title)
        ax.set_xlabel("xyz"[a] + " (mm)")
        ax.set_ylabel("xyz"[b] + " (mm)")
        ax.set_aspect("equal", adjustable="datalim")
    fig.axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{mesh.name}: {mesh.n_nodes} nodes, {mesh.n_triangles} triangles")
    fig.tight_layout()
    return fig


def plot_modes(mean_disp: np.ndarray, modes: np.ndarray, mesh: LipMesh,
               sd: np.ndarray | None = None, fractions: np.ndarray | None = None,
               units_per_mm: np.ndarray | None = None, title: str = "",
               n_show: int = 3) -> Figure:
    """Basu & Pentland (1997) Fig. 9: the mean displacement and the first characteristic modes.

    Column 1: the rest shape (grey) and rest + mean displacement (black); then, per mode, the
    mean shape (grey) and mean -/+ 2 sd along the mode (blue/red). Top row frontal (x-y), bottom
    row profile (z-y), drawn in mm. mean_disp (N, 3) and modes (k, N, 3) are in model units with
    `units_per_mm` (3,) model units per mm (default 1: mm); sd (k,) in model units; fractions (k,)
    of the total variance, printed per mode.
    """
    n_show = min(n_show, len(modes))
    k_unit = np.ones(3) if units_per_mm is None else np.asarray(units_per_mm, dtype=float)
    sd = np.ones(len(modes)) if sd is None else np.asarray(sd)
    mean_mm = mean_disp / k_unit
    fig = Figure(figsize=(3.4 * (n_show + 1), 6.4))
    for row, (view, a, b) in enumerate(_VIEWS):
        ax = fig.add_subplot(2, n_show + 1, row * (n_show + 1) + 1)
        _draw(ax, mesh, mesh.nodes, a, b, color="0.75")
        _draw(ax, mesh, mesh.nodes + mean_mm, a, b, color="k", lw=0.7)
        set_title(ax, f"mean displacement\n{view}", fontsize=9)
        for j in range(n_show):
            ax = fig.add_subplot(2, n_show + 1, row * (n_show + 1) + j + 2)
            base = mesh.nodes + mean_mm
            _draw(ax, mesh, base, a, b, color="0.75")
            for sign, color in ((-2, "tab:blue"), (2, "tab:red")):
                _draw(ax, mesh, base + sign * sd[j] * modes[j] / k_unit, a, b, color, lw=0.7)
            share = "" if fractions is None else f", {100 * fractions[j]:.1f} % of variance"
            set_title(ax, f"mode {j + 1}{share}\n{view}", fontsize=9)
    for ax in fig.axes:
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
    for i, ax in enumerate(fig.axes):
        view = _VIEWS[i // (n_show + 1)]
        ax.set_xlabel("xyz"[view[1]] + " (mm)", fontsize=8)
        ax.set_ylabel("xyz"[view[2]] + " (mm)", fontsize=8)
    handles = [Line2D([], [], color="0.75", label="rest shape / mean shape"),
               Line2D([], [], color="k", label="rest + mean displacement"),
               Line2D([], [], color="tab:blue", label="mean - 2 sd along the mode"),
               Line2D([], [], color="tab:red", label="mean + 2 sd along the mode")]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle(title or "Mean displacement and characteristic modes "
                 "(Basu & Pentland 1997, Fig. 9)", fontsize=11)
    fig.tight_layout(rect=(0, 0.05, 1, 0.97))
    return fig
