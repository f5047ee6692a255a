"""Lip meshes: the parametric generator, the canonical MediaPipe lip band, validation, OBJ."""


import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.io.obj import read_obj
from facemotion.lips.mesh import (
    INNER_RING,
    OUTER_RING,
    PAPER_MODEL_EXTENT,
    LipMesh,
    canonical_lip_mesh,
    extents,
    lip_band,
    model_units_per_mm,
    parametric_lip_mesh,
    triangle_areas,
)

DATA = SHARED_DATA
OBJ = DATA / "mesh" / "canonical_face_model.obj"


def test_parametric_mesh_size_roles_and_geometry():
    m = parametric_lip_mesh()
    # the paper's counts (Sec. 2.1): 336 faces, 204 nodes, 612 DOF
    assert (m.n_nodes, m.n_triangles, 3 * m.n_nodes) == (204, 336, 612)
    # 4 grounded nodes at the strip's far end: 612 - 12 = 600 free DOF, the columns of P
    # (Sec. 4.1); both ends of the row and two between, mirror-symmetric
    assert len(m.fixed) == 4 and set(m.role[m.fixed]) == {"fixed"}
    assert 3 * len(m.free_nodes) == 600
    far = np.arange(204 - 11, 204)
    assert set(m.fixed) <= set(far) and {far[0], far[-1]} <= set(m.fixed)
    np.testing.assert_allclose(np.sort(m.nodes[m.fixed, 0]), -np.sort(m.nodes[m.fixed, 0])[::-1])
    assert len(m.band_nodes) == 5 * 32
    # the strip hangs from the top of the upper lip and runs back into the mouth (Sec. 2.4)
    strip = np.isin(m.role, ("strip", "fixed"))
    assert m.nodes[strip, 2].max() < m.nodes[m.role == "inner", 2].max()
    assert m.nodes[m.fixed, 1].min() > 0 and m.nodes[m.fixed, 2].max() < -10
    # mirror symmetric about x = 0 (the paper made its mesh symmetric, Sec. 2.1)
    mirrored = m.nodes * [-1, 1, 1]
    d = np.linalg.norm(mirrored[:, None] - m.nodes[None], axis=2)
    assert np.all(d.min(axis=1) < 1e-9)
    width = np.ptp(m.nodes[m.role == "outer", 0])
    assert 45 < width < 55                               # about 50 mm wide
    assert np.ptp(m.nodes[m.band_nodes, 2]) > 5         # curved in z
    assert (m.element_kind == "ridge").sum() == 64
    assert m.labels[17] == "n017" and m.index("n017") == 17


def test_canonical_band_has_80_vertices_120_triangles_and_drops_18():
    verts, faces = read_obj(OBJ)
    assert verts.shape == (468, 3) and faces.shape == (898, 3)
    band = lip_band(faces)
    assert len(band) == 120
    assert len(np.unique(faces[band])) == 80
    inner = set(INNER_RING)
    closing = [t for t in range(len(faces)) if set(faces[t].tolist()) <= inner]
    assert len(closing) == 18 and not set(closing) & set(band.tolist())
    m = canonical_lip_mesh(OBJ, strip_rings=2)
    assert len(m.band_nodes) == 80 and (m.element_kind != "strip").sum() == 120
    assert {m.labels[i] for i in m.band_nodes} >= {f"L{i:03d}" for i in OUTER_RING + INNER_RING}
    assert len(m.fixed) == 20
    assert 40 < np.ptp(m.nodes[m.band_nodes, 0]) < 60   # cm converted to mm


def test_canonical_band_nodes_override_geometry():
    m = canonical_lip_mesh(OBJ)
    moved = {m.labels[i]: m.nodes[i] + [0, 0, 1.0] for i in m.band_nodes}
    m2 = canonical_lip_mesh(OBJ, band_nodes=moved)
    np.testing.assert_allclose(m2.nodes[m.band_nodes], m.nodes[m.band_nodes] + [0, 0, 1.0])


def _square():
    nodes = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    kw = dict(fixed=[3], role=["outer", "lip", "inner", "fixed"], part=["upper"] * 4,
              labels=["a", "b", "c", "d"])
    return nodes, kw


def test_valid_small_mesh_and_areas():
    nodes, kw = _square()
    m = LipMesh(nodes, np.array([[0, 1, 2], [0, 2, 3]]), element_kind=["lip", "lip"], **kw)
    np.testing.assert_allclose(triangle_areas(m.nodes, m.triangles), [0.5, 0.5])


@pytest.mark.parametrize("tris, match", [
    ([[0, 1, 2], [2, 1, 0]], r"triangles \[0, 1\] are duplicates"),
    ([[0, 1, 2], [0, 2, 7]], r"triangle 1 .* outside"),
    ([[0, 1, 1], [0, 2, 3]], r"triangle 0 .* repeats a node"),
])
def test_bad_triangles(tris, match):
    nodes, kw = _square()
    with pytest.raises(InputError, match=match):
        LipMesh(nodes, np.array(tris), element_kind=["lip", "lip"], **kw)


def test_degenerate_triangle_named():
    nodes, kw = _square()
    nodes[2] = [0.5, 0.0, 0.0]   # collinear with nodes 0 and 1
    with pytest.raises(InputError, match=r"triangle 0 .* degenerate"):
        LipMesh(nodes, np.array([[0, 1, 2], [0, 2, 3]]), element_kind=["lip", "lip"], **kw)


def test_unknown_label_names_it():
    with pytest.raises(InputError, match="'L999' is not a node"):
        parametric_lip_mesh().index("L999")


def test_obj_reader_face_forms(tmp_path):
    p = tmp_path / "m.obj"
    p.write_text("# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\n"
                 "f 1/1/1 2/1/1 3/1/1\nf 1//1 3//1 4//1\nf -4 -2 -1\nf 1 2 3 4\n")
    v, f = read_obj(p)
    assert v.shape == (4, 3)
    assert f.tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3], [0, 1, 2], [0, 2, 3]]


def test_obj_reader_bad_line(tmp_path):
    p = tmp_path / "bad.obj"
    p.write_text("v 0 0 0\nv 1 x 0\n")
    with pytest.raises(InputError, match="line 2"):
        read_obj(p)


def test_model_units_per_mm_gives_the_papers_extents():
    m = parametric_lip_mesh()
    k = model_units_per_mm(m, PAPER_MODEL_EXTENT)
    scaled = m.nodes * k
    # independent reference: the bounding box by sorting each axis
    size = np.array([np.sort(scaled[:, a])[-1] - np.sort(scaled[:, a])[0] for a in range(3)])
    np.testing.assert_allclose(size, [2.35, 2.83, 5.05], rtol=1e-12)
    np.testing.assert_allclose(extents(m.nodes), [50.0, size[1] / k[1], size[2] / k[2]])
    assert np.all(model_units_per_mm(m, None) == 1)
    with pytest.raises(InputError, match="model_extent"):
        model_units_per_mm(m, (2.35, -1.0, 5.05))
