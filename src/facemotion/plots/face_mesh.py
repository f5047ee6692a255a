"""A face mesh whose vertices are labelled markers, placed on a talker's neutral face.

Dense trackers give points that are the vertices of a known triangle mesh (MediaPipe's 468
landmarks: vertex i of the canonical face model is landmark ``L{i:03d}``). Maps over the face
are then drawn on the mesh's triangles, one value per vertex, instead of interpolated over a
grid of the markers' convex hull.

Placement on a talker: a vertex that is one of the talker's markers sits at that marker's
neutral position; the other vertices follow the mesh's own shape, carried onto the talker by
the similarity transform (scale, rotation, translation; Umeyama 1991, least squares) that best
maps the mesh's matched vertices onto their markers. So the mesh's units do not matter.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError

DEFAULT_LABELS = "L{i:03d}"


@dataclass
class FaceMesh:
    vertices: np.ndarray   # (V, 3) in the mesh's own units
    triangles: np.ndarray  # (T, 3) 0-based vertex indices
    labels: list[str]      # one marker label per vertex
    name: str = "mesh"

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=float)
        self.triangles = np.asarray(self.triangles, dtype=np.int64)
        self.labels = [str(s) for s in self.labels]
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise InputError(f"{self.name}: vertices must be (V, 3), got {self.vertices.shape}")
        if len(self.labels) != len(self.vertices):
            raise InputError(f"{self.name}: {len(self.labels)} labels for "
                             f"{len(self.vertices)} vertices")
        if len(set(self.labels)) != len(self.labels):
            raise InputError(f"{self.name}: vertex labels are not unique")
        t = self.triangles
        if t.ndim != 2 or t.shape[1] != 3 or len(t) == 0 or t.min() < 0 \
                or t.max() >= len(self.vertices):
            raise InputError(f"{self.name}: triangles must be (T, 3) indices into the "
                             f"{len(self.vertices)} vertices")


def read_face_mesh(path: str | Path, label_format: str = DEFAULT_LABELS) -> FaceMesh:
    """A Wavefront OBJ mesh; vertex i (0-based) gets the label ``label_format.format(i=i)``
    (default ``L{i:03d}``, MediaPipe landmark numbering as in the GRID tracks)."""
    from facemotion.io.obj import read_obj

    path = Path(path)
    if "{i" not in label_format:
        raise InputError(f"mesh vertex label format {label_format!r} must contain {{i}} "
                         "(e.g. L{i:03d})")
    v, f = read_obj(path)
    if len(v) == 0 or len(f) == 0:
        raise InputError(f"{path}: no vertices or no triangles")
    return FaceMesh(v, f, [label_format.format(i=i) for i in range(len(v))], name=str(path))


def similarity_transform(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray,
                                                                      np.ndarray]:
    """Scale s, rotation R (proper) and translation t minimising ||s R src_i + t - dst_i||^2
    (Umeyama 1991, Eqs. 40-42)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1.0
    R = U @ D @ Vt
    var = (a ** 2).sum() / len(src)
    s = float(np.trace(np.diag(S) @ D) / var) if var > 0 else 1.0
    return s, R, mu_d - s * R @ mu_s


@dataclass
class PlacedMesh:
    """A mesh on a talker: vertex positions (mm, head axes) and, per vertex, the index of its
    marker in the talker's labels (-1 for a vertex that is not a marker)."""

    positions: np.ndarray   # (V, 3) mm
    triangles: np.ndarray   # (T, 3)
    marker_index: np.ndarray  # (V,) int
    labels: list[str]


def place_mesh(mesh: FaceMesh, neutral: np.ndarray, labels: Sequence[str]) -> PlacedMesh:
    """Put ``mesh`` on a talker whose markers ``labels`` sit at ``neutral`` (n, 3) mm."""
    labels = [str(s) for s in labels]
    pos = {s: i for i, s in enumerate(labels)}
    marker_index = np.array([pos.get(s, -1) for s in mesh.labels], dtype=np.int64)
    matched = np.flatnonzero(marker_index >= 0)
    if matched.size < 3:
        raise InputError(f"{mesh.name}: only {matched.size} of its vertex labels "
                         f"({mesh.labels[0]}, ...) are among the talker's markers "
                         f"({labels[0]}, ...): need at least 3 to place it")
    src, dst = mesh.vertices[matched], np.asarray(neutral, dtype=float)[marker_index[matched]]
    if np.linalg.matrix_rank(src - src.mean(axis=0), tol=1e-9 * np.abs(src).max()) < 2:
        raise InputError(f"{mesh.name}: the matched vertices are collinear: cannot place it")
    s, R, t = similarity_transform(src, dst)
    positions = s * mesh.vertices @ R.T + t
    positions[matched] = dst
    return PlacedMesh(positions, mesh.triangles, marker_index, mesh.labels)


def front_facing(xy: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles that face the viewer of the frontal (x, y) projection: those whose signed
    area has the sign of the mesh's total (area-weighted majority); folded-over ones at the
    face's sides and degenerate ones (zero area) are left out."""
    p = xy[triangles]
    area = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                  - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    sign = 1.0 if area.sum() >= 0 else -1.0
    return triangles[sign * area > 0]
