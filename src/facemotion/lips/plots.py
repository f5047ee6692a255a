"""Figures of the lip model: the mesh (tracked and fixed nodes marked) and its learned modes
(paper Fig. 9: mean displacement and mean +- 2 sd along the first modes).

Matplotlib `Figure` objects built without pyplot's global state; deterministic.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from facemotion.lips.mesh import LipMesh

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
        ax.set_title(title)
        ax.set_xlabel("xyz"[a] + " (mm)")
        ax.set_ylabel("xyz"[b] + " (mm)")
        ax.set_aspect("equal", adjustable="datalim")
    fig.axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{mesh.name}: {mesh.n_nodes} nodes, {mesh.n_triangles} triangles")
    fig.tight_layout()
    return fig


def plot_modes(mean_disp: np.ndarray, modes: np.ndarray, mesh: LipMesh,
               sd: np.ndarray | None = None, n_show: int = 3) -> Figure:
    """Paper Fig. 9: the mean deformed mesh, then mean -/+ 2 sd along the first modes
    (frontal view, x-y; grey = rest shape). modes (k, N, 3); sd (k,) mm (default: 1)."""
    n_show = min(n_show, len(modes))
    sd = np.ones(len(modes)) if sd is None else np.asarray(sd)
    fig = Figure(figsize=(3.2 * (n_show + 1), 6))
    ax = fig.add_subplot(2, n_show + 1, 1)
    _draw(ax, mesh, mesh.nodes, 0, 1, color="0.8")
    _draw(ax, mesh, mesh.nodes + mean_disp, 0, 1, color="k")
    ax.set_title("mean displacement")
    for j in range(n_show):
        for row, (sign, color) in enumerate(((-2, "tab:blue"), (2, "tab:red"))):
            ax = fig.add_subplot(2, n_show + 1, row * (n_show + 1) + j + 2)
            _draw(ax, mesh, mesh.nodes + mean_disp, 0, 1, color="0.8")
            _draw(ax, mesh, mesh.nodes + mean_disp + sign * sd[j] * modes[j], 0, 1, color)
            ax.set_title(f"mode {j + 1}: mean {'+' if sign > 0 else '-'} 2 sd")
    for ax in fig.axes:
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    return fig
