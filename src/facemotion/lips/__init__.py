"""The lip model of Basu & Pentland (1997): a finite-element thin-shell lip mesh, fitted to
tracked points with minimal force, whose deformations are learned as modes and used to
reconstruct the whole lip from a few observations.

Three steps, each one call::

    from facemotion import lips

    talker = lips.make_virtual_talker()            # a mesh, tracks and a planted truth
    U = lips.fit(mesh, goals, tracked)             # minimal-force fit (eqs. 8-10)
    model = lips.modes(U[:140])                    # PCA of the deformations (eqs. 11-13)
    U_hat = lips.reconstruct(model, y, observed)   # LLSE from partial observations (Sec. 5)

``run_lip_model`` is the whole study of one recording (normalisation, fit, modes, the paper's
three views); the workflow calls it.  Names load on first use.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from facemotion.lips.mesh import LipMesh
    from facemotion.lips.pca import Modes

_LAZY = {
    "parametric_lip_mesh": ("facemotion.lips.mesh", "parametric_lip_mesh"),
    "canonical_lip_mesh": ("facemotion.lips.mesh", "canonical_lip_mesh"),
    "LipMesh": ("facemotion.lips.mesh", "LipMesh"),
    "Modes": ("facemotion.lips.pca", "Modes"),
    "make_virtual_talker": ("facemotion.lips.virtual", "make_virtual_talker"),
    "run_lip_model": ("facemotion.lips.pipeline", "run_lip_model"),
}

__all__ = ["fit", "modes", "reconstruct", *_LAZY]


def fit(mesh: LipMesh, goals, tracked, **stiffness) -> np.ndarray:
    """Minimal-force fit of the mesh to goal displacements of tracked nodes (eqs. 8-10).

    goals: (frames, m, 3) mm, the displacements of the m ``tracked`` nodes (labels or node
    indices, in the order of ``goals``) from the rest shape.  stiffness: the material settings
    of :func:`facemotion.lips.fem.assemble_stiffness` (E, nu, ridge_factor, strip_factor,
    thickness).  Returns the displacements of every node, (frames, N, 3) mm; fixed nodes 0.
    """
    from facemotion.lips.fem import assemble_stiffness
    from facemotion.lips.fitting import MinimalForceFitter

    K = assemble_stiffness(mesh, **stiffness)
    return MinimalForceFitter(mesh, K, tracked).fit(goals)


def modes(displacements, n_modes: int | None = None) -> Modes:
    """Learned deformation modes: PCA of fitted displacements (eqs. 11-13).

    displacements: (frames, N, 3) from :func:`fit`, or (frames, D).  Returns a
    :class:`~facemotion.lips.pca.Modes` over the D = 3N flattened DOF (node-major: x, y, z
    of node 0, then node 1, ...); ``.table()`` gives the variance of each mode as pandas.
    """
    import numpy as np

    from facemotion.lips.pca import pca_svd

    data = np.asarray(displacements, dtype=float)
    return pca_svd(data.reshape(len(data), -1), n_modes)


def reconstruct(model: Modes, y, observed, noise_var: float = 0.0,
                n_modes: int | None = None) -> np.ndarray:
    """Whole displacement vectors from partial observations by LLSE (Sec. 5).

    y: (frames, p) observed values (mm) of the DOF ``observed`` (p indices into the flattened
    D DOF of ``model``).  noise_var: observation noise variance (mm^2); 0 is the noise-free
    limit (least squares on the modes).  n_modes: use the first n modes (default all).
    Returns (frames, D) mm.
    """
    from facemotion.lips.llse import LLSE

    return LLSE.from_modes(model, n_modes).estimate(y, observed, noise_var)


class _Package(types.ModuleType):
    """Keeps the function `modes` when the deprecated 0.1 path facemotion.lips.modes is
    imported (the import system sets the package attribute of a submodule's name to it)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in __all__ and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'facemotion.lips' has no attribute {name!r}")
    module, attr = _LAZY[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
