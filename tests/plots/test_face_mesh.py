"""Face mesh: reading, placement on a talker against a planted transform, maps drawn on it."""


import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from helpers import SHARED_DATA
from matplotlib.collections import TriMesh  # noqa: E402
from scipy.spatial import Delaunay  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from facemotion.errors import InputError  # noqa: E402
from facemotion.plots.face_mesh import (
    FaceMesh,
    front_facing,
    place_mesh,
    read_face_mesh,
    similarity_transform,
)
from facemotion.plots.facemap import mesh_values  # noqa: E402
from facemotion.plots.regions import plot_orthogonal_directions, plot_region_maps  # noqa: E402

SHARED = SHARED_DATA


def dome(n_side=9):
    """A dome of vertices over a square (mesh units), Delaunay triangles, outward (+z) facing."""
    g = np.linspace(-1.0, 1.0, n_side)
    x, y = np.meshgrid(g, g)
    xy = np.column_stack([x.ravel(), y.ravel()])
    z = 1.5 - 0.4 * (xy ** 2).sum(axis=1)
    tri = Delaunay(xy).simplices
    return np.column_stack([xy, z]), tri


def test_similarity_transform_recovers_a_planted_one():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(30, 3))
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    dst = 7.5 * src @ R.T + [10.0, -4.0, 2.0]
    s, Rf, t = similarity_transform(src, dst)
    assert s == pytest.approx(7.5)
    np.testing.assert_allclose(Rf, R, atol=1e-12)
    np.testing.assert_allclose(t, [10.0, -4.0, 2.0], atol=1e-10)


def test_place_mesh_puts_markers_on_their_vertices_and_carries_the_rest():
    verts, tri = dome()
    labels = [f"V{i}" for i in range(len(verts))]
    mesh = FaceMesh(verts, tri, labels, name="dome")
    # the talker: every third vertex is a marker, the mesh scaled to mm, turned and moved
    R = Rotation.from_rotvec([0.05, 0.1, -0.02]).as_matrix()
    true = 40.0 * verts @ R.T + [3.0, -20.0, 60.0]
    markers = list(range(0, len(verts), 3))
    neutral = true[markers] + np.random.default_rng(1).normal(scale=1e-9, size=(len(markers), 3))
    placed = place_mesh(mesh, neutral, [labels[i] for i in markers])
    np.testing.assert_array_equal(placed.positions[markers], neutral)
    np.testing.assert_allclose(placed.positions, true, atol=1e-6)
    assert (placed.marker_index[markers] == np.arange(len(markers))).all()
    assert (np.delete(placed.marker_index, markers) == -1).all()
    with pytest.raises(InputError, match="dome.*need at least 3"):
        place_mesh(mesh, neutral[:2], ["V0", "Chin"])


def test_front_facing_drops_folded_and_flat_triangles():
    xy = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [2, 2]], float)
    tris = np.array([[0, 1, 2], [1, 3, 2], [1, 2, 3], [0, 3, 4]])  # ccw, ccw, cw, flat
    kept = front_facing(xy, tris)
    np.testing.assert_array_equal(kept, [[0, 1, 2], [1, 3, 2]])


def test_canonical_face_mesh_reads_with_landmark_labels():
    path = SHARED / "mesh" / "canonical_face_model.obj"
    if not path.is_file():
        pytest.fail(f"shared data not found at {SHARED}; set FACEMOTION_SHARED_DATA")
    mesh = read_face_mesh(path)
    assert mesh.vertices.shape == (468, 3) and mesh.triangles.shape == (898, 3)
    assert mesh.labels[0] == "L000" and mesh.labels[467] == "L467"
    with pytest.raises(InputError, match="must contain"):
        read_face_mesh(path, "L")


def _talker(n_side=9):
    verts, tri = dome(n_side)
    labels = [f"V{i}" for i in range(len(verts))]
    neutral = 40.0 * verts
    return FaceMesh(verts, tri, labels, name="dome.obj"), neutral, labels


def test_region_maps_on_a_mesh_colour_each_vertex_by_its_coefficient():
    mesh, neutral, labels = _talker()
    mains = ["V0", "V40", "V80"]
    secondary = [s for s in labels if s not in mains]
    rng = np.random.default_rng(2)
    X = pd.DataFrame(rng.uniform(0.0, 0.9, (3, len(secondary))), index=mains,
                     columns=secondary)
    fig = plot_region_maps(neutral, labels, X, mesh=mesh)
    panels = [ax for ax in fig.axes if ax.get_title().startswith("main marker")]
    assert [ax.get_title() for ax in panels] == [f"main marker {m}" for m in mains]
    assert "dome.obj (81 vertices, 81 of them markers" in fig.get_suptitle()
    for ax, m in zip(panels, mains, strict=True):
        (art,) = [c for c in ax.collections if isinstance(c, TriMesh)]
        # vertex colours: the main marker 1, the other mains 0, secondary j X[m, j]
        expect = np.array([1.0 if s == m else 0.0 if s in mains else X.loc[m, s]
                           for s in labels])
        np.testing.assert_allclose(art.get_array(), expect)
        assert m in [t.get_text() for t in ax.texts]
        # every triangle of the dome faces the viewer and is drawn, back to front
        assert len(art.get_paths()) == len(mesh.triangles)
    fig = plot_orthogonal_directions(neutral, labels, np.triu(rng.normal(size=(81, 81)))
                                     + 5 * np.eye(81), labels, n_pivots=2, mesh=mesh)
    assert [ax.get_title() for ax in fig.axes if ax.get_title().startswith("q")] == [
        "q1: pivot V0", "q2: pivot V1"]


def test_mesh_values_interpolate_between_markers_and_stop_at_their_hull():
    mesh, neutral, labels = _talker()
    markers = [i for i in range(81) if i % 9 in (0, 2, 4, 6, 8) and i // 9 in (0, 2, 4, 6)]
    placed = place_mesh(mesh, neutral[markers], [labels[i] for i in markers])
    plane = 0.3 * neutral[markers, 0] - 0.1 * neutral[markers, 1] + 2.0
    v = mesh_values(placed, neutral[markers, :2], plane)
    inside = np.isfinite(v)
    # a plane is reproduced exactly by the cubic interpolant; outside the hull: no value
    np.testing.assert_allclose(v[inside], 0.3 * placed.positions[inside, 0]
                               - 0.1 * placed.positions[inside, 1] + 2.0, atol=1e-6)
    assert not inside[8 * 9:].any()  # the top row lies beyond the markers (rows 0-6)
