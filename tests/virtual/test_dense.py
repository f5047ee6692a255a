"""The dense virtual talker's mesh: the canonical face in the head frame, the open mouth, the
lip sides, and the subdivision to 5,023 vertices, against invariants computed independently
(areas, orientation, midpoints, the Euler characteristic) and the mesh file itself."""


import numpy as np
import pytest
from helpers import SHARED_DATA
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.io.obj import read_obj
from facemotion.lips.mesh import INNER_RING
from facemotion.virtual.dense import (
    ANATOMY_LANDMARKS,
    CANONICAL_MESH,
    FINE_VERTICES,
    dense_face,
    lip_sides,
    mesh_path,
    read_canonical_mesh,
    subdivide_longest_edges,
)
from facemotion.virtual.talker import make_talker

SHARED = SHARED_DATA
MESH = SHARED / CANONICAL_MESH


def _area_vectors(v, t):
    return 0.5 * np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])


def _edges(t):
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)


def test_missing_mesh_is_one_line_naming_the_setting(tmp_path):
    with pytest.raises(InputError, match=r"canonical face mesh .* set shared_data") as e:
        mesh_path(tmp_path)
    assert "\n" not in str(e.value)
    assert mesh_path(SHARED) == MESH


def test_mouth_opened_by_dropping_exactly_its_18_triangles():
    v0, f0 = read_obj(MESH)
    v, f = read_canonical_mesh(MESH)
    dropped = {tuple(sorted(x)) for x in f0} - {tuple(sorted(x)) for x in f}
    assert len(f0) - len(f) == len(dropped) == 18
    assert all(set(tri) <= set(INNER_RING) for tri in dropped)
    # the inner lip contour is now a boundary: each of its edges borders one triangle
    edges, counts = _edges(f)
    boundary = {tuple(e) for e, c in zip(edges, counts, strict=True) if c == 1}
    ring = [tuple(sorted((INNER_RING[i], INNER_RING[(i + 1) % len(INNER_RING)])))
            for i in range(len(INNER_RING))]
    assert set(ring) <= boundary


def test_lip_sides():
    v, f = read_canonical_mesh(MESH)
    s = lip_sides(v, f)
    assert np.isfinite(s).sum() == 80  # the lip band's vertices (data README)
    assert s[13] == 0.0 and s[0] == 0.0 and s[14] == 1.0 and s[17] == 1.0
    assert s[61] == s[291] == s[78] == s[308] == 0.5
    assert np.isnan(s[1]) and np.isnan(s[152])  # nose tip, chin


def test_head_frame_is_a_translation_of_the_mesh_in_mm():
    talker = make_talker(2)
    face = dense_face(MESH, talker.anatomy)
    v_cm, _ = read_canonical_mesh(MESH)
    np.testing.assert_allclose(face.vertices, 10.0 * v_cm + face.translation_mm, atol=1e-12)
    # 89 mm between the outer eye corners, the talker's right eye at negative x
    assert np.linalg.norm(face.vertices[33] - face.vertices[263]) == pytest.approx(88.9, abs=0.1)
    assert face.vertices[33, 0] < 0 < face.vertices[263, 0]
    # the translation is the least-squares one: mean residual over the landmarks is zero
    lm = list(ANATOMY_LANDMARKS.values())
    target = talker.anatomy[[int(m) - 1 for m in ANATOMY_LANDMARKS]]
    np.testing.assert_allclose((face.vertices[lm] - target).mean(axis=0), 0.0, atol=1e-9)
    a = face.anatomy(talker.anatomy)
    np.testing.assert_array_equal(a[33], face.vertices[291])  # marker 34 = left corner
    np.testing.assert_array_equal(a[0], talker.anatomy[0])    # roles not named: unchanged


def test_subdivision_to_5023_vertices_keeps_the_surface():
    talker = make_talker(2)
    coarse = dense_face(MESH, talker.anatomy)
    fine = dense_face(MESH, talker.anatomy, FINE_VERTICES)
    assert fine.n == FINE_VERTICES and fine.labels[0] == "V0000"
    np.testing.assert_array_equal(fine.vertices[:468], coarse.vertices)
    new = np.arange(468, fine.n)
    p = fine.parents[new]
    np.testing.assert_allclose(fine.vertices[new],
                               0.5 * (fine.vertices[p[:, 0]] + fine.vertices[p[:, 1]]))
    # midpoint splits of flat triangles: total area and the oriented area vector unchanged
    a0, a1 = _area_vectors(coarse.vertices, coarse.triangles), \
        _area_vectors(fine.vertices, fine.triangles)
    np.testing.assert_allclose(a1.sum(axis=0), a0.sum(axis=0), rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(a1, axis=1).sum(),
                               np.linalg.norm(a0, axis=1).sum(), rtol=1e-10)
    assert (np.linalg.norm(a1, axis=1) > 0).all()
    # a manifold with the same Euler characteristic, edges shared by at most two triangles
    for face in (coarse, fine):
        edges, counts = _edges(face.triangles)
        assert counts.max() == 2
    chi = [f.n - len(_edges(f.triangles)[0]) + len(f.triangles) for f in (coarse, fine)]
    assert chi[0] == chi[1]
    # longest edges split first: the fine mesh's edges are even (the canonical one's are not)
    edges, _ = _edges(fine.triangles)
    length = np.linalg.norm(fine.vertices[edges[:, 0]] - fine.vertices[edges[:, 1]], axis=1)
    assert length.max() < 5.0 < 28.0
    # lip sides carried as the mean of the split edge's ends
    ok = np.isfinite(fine.lip_side[new])
    np.testing.assert_allclose(fine.lip_side[new][ok],
                               0.5 * fine.lip_side[p[ok, 0]] + 0.5 * fine.lip_side[p[ok, 1]])


def test_subdivision_refuses_fewer_vertices():
    v = np.eye(3)
    with pytest.raises(InputError, match="already has 3"):
        subdivide_longest_edges(v, np.array([[0, 1, 2]]), 2)


# ---------------------------------------------------------------- the talker, planted truth

def _load(paths, fmt, n_train):
    from facemotion.ingest.loading import load_dataset
    from facemotion.virtual.talker import HEAD_LABELS

    n = len(paths)
    return load_dataset([str(p) for p in paths], fmt, head_markers=list(HEAD_LABELS),
                        exclude_markers=list(HEAD_LABELS), train=list(range(n_train)),
                        heldout=list(range(n_train, n)))


def test_planted_fields_are_the_rank_and_that_many_pivots_predict_every_vertex(tmp_path):
    """Without tissue motion, noise and head motion, A of the 468 vertices (written as TRC,
    read and loaded by the study's path) is sum over sources k and axes c of s_k(t) e_c times
    the field component D_k[:, c], so its rank is that of the planted field components (from
    the fields alone, numpy's SVD), and that many pivots of the training sentences predict
    every vertex of the held-out ones exactly; one fewer does not."""
    from facemotion.ranking.routes import rank_markers
    from facemotion.regions.prediction import error_curve
    from facemotion.virtual.dense import simulate_dense, write_dense_subject

    subj = simulate_dense("D468", seed=3, n_sentences=8, shared_data=SHARED, noise_mm=0.0,
                          tissue_rms_mm=0.0, head_rotation_deg=0.0, head_translation_mm=0.0)
    D = subj.truth["fields"]
    K = D.shape[0]
    comps = np.stack([D[k, :, c] for k in range(K) for c in range(3) if D[k, :, c].any()], 1)
    sv = np.linalg.svd(comps, compute_uv=False)
    r_star = int(np.count_nonzero(sv > 1e-10 * sv[0]))
    assert 2 * K <= r_star < comps.shape[1]   # some components are combinations of others
    paths = write_dense_subject(subj, tmp_path, "D", "trc")
    ds = _load(paths, "trc", 6).displacements
    assert ds.labels == [f"L{i:03d}" for i in range(468)]
    train = ds.row_sentence < 6
    s = np.linalg.svd(ds.A[train], compute_uv=False)
    # TRC keeps 6 decimals of a mm: singular values of that rounding ~1e-4 mm
    assert s[r_star] < 1e-3 and s[r_star] < 1e-2 * s[r_star - 1]
    rk = rank_markers(ds.A[train], ds.labels)
    curve = error_curve(rk, ds.A[~train], ds.labels, k_max=r_star).set_index("k")
    err = curve["max_abs_error_mm"]
    assert err[r_star] < 1e-3 and err[r_star] < 1e-2 * err[r_star - 1]
    # the displacements are the planted fields times the planted courses (head frame)
    planted = (subj.truth["source_courses"] @ D.reshape(K, -1)).reshape(-1, 468, 3)
    np.testing.assert_allclose(ds.A.reshape(-1, 3, 468).transpose(0, 2, 1), planted,
                               atol=2e-6)


@pytest.mark.parametrize("noise,tol", [(0.0, 2e-3), (None, 0.25)])
def test_loaded_displacements_are_the_planted_ones_under_head_motion(tmp_path, noise, tol):
    """The talker with head motion (no tissue, so the truth is closed-form: s D) through C3D
    and the loading path's head alignment on H1-H6: without noise the planted head-frame
    displacements come back to C3D's float32 precision; with the talker's noise (0.08 mm per
    axis on every sample, the sentence's first frame and the six band markers the alignment
    rests on) to within 0.25 mm per axis of a 0.8 mm signal."""
    from facemotion.virtual.dense import simulate_dense, write_dense_subject

    subj = simulate_dense("D468", seed=5, n_sentences=3, shared_data=SHARED,
                          tissue_rms_mm=0.0, noise_mm=noise)
    ds = _load(write_dense_subject(subj, tmp_path, "D", "c3d"), "c3d", 3).displacements
    t = subj.truth
    K = t["fields"].shape[0]
    planted = (t["source_courses"] @ t["fields"].reshape(K, -1)).reshape(-1, 468, 3)
    # the loading path's head frame is the world frame at the dataset's first frame (its head
    # reference), i.e. the talker's head frame turned by the planted head rotation there
    R0 = Rotation.from_rotvec(t["head_motion"][0, :3]).as_matrix()
    expected = planted @ R0.T
    got = ds.A.reshape(-1, 3, 468).transpose(0, 2, 1)
    assert np.sqrt(np.mean(planted ** 2)) > 0.5                    # a moving face
    assert np.sqrt(np.mean((got - expected) ** 2)) < tol


def test_fine_talker_equals_the_coarse_one_at_the_canonical_vertices():
    """The same seed: D5023's noise-free motion at V0000-V0467 is D468's at L000-L467 (the
    tissue field extended by its kernel is exact at the nodes), and a new vertex's motion lies
    between its edge's ends' (fields and tissue both smooth)."""
    from facemotion.virtual.dense import simulate_dense

    kw = dict(seed=7, n_sentences=2, shared_data=SHARED, noise_mm=0.0)
    fine = simulate_dense("D5023", **kw)
    coarse = simulate_dense("D468", **kw)
    for rf, rc in zip(fine.recordings, coarse.recordings, strict=True):
        assert rf.labels[:468] == [f"V{i:04d}" for i in range(468)]
        assert rf.n_markers == 5023 + 6
        np.testing.assert_allclose(rf.points[:, :468], rc.points[:, :468], atol=1e-9)
        np.testing.assert_allclose(rf.points[:, -6:], rc.points[:, -6:], atol=1e-9)
    p = fine.truth["parents"][468:]
    disp = fine.recordings[0].points - fine.recordings[0].points[0]
    mid = 0.5 * (disp[:, p[:, 0]] + disp[:, p[:, 1]])
    scale = np.abs(disp[:, :468]).max()
    assert np.abs(disp[:, 468:5023] - mid).max() < 0.25 * scale


def test_lips_part_with_the_jaw():
    """The jaw carries the lower lip (landmarks 14, 17) and barely the upper (13, 0): the
    mouth opens instead of stretching a closed surface."""
    from facemotion.virtual.dense import simulate_dense

    t = simulate_dense("D468", n_sentences=1, shared_data=SHARED).truth
    jaw = t["fields"][0, :, 1]
    assert jaw[14] < -2.0 and jaw[17] < -2.0
    assert abs(jaw[13]) < 0.3 * abs(jaw[14]) and abs(jaw[0]) < 0.3 * abs(jaw[17])


@pytest.mark.parametrize("fmt", ["trc", "c3d", "openface_csv"])
def test_written_formats_read_back(tmp_path, fmt):
    from facemotion.io.registry import read_recording
    from facemotion.virtual.dense import dense_layout, simulate_dense, write_dense_subject

    subj = simulate_dense("D468", n_sentences=1, shared_data=SHARED)
    (path,) = write_dense_subject(subj, tmp_path, "D", fmt)
    rec = read_recording(path, fmt)
    src = subj.recordings[0]
    np.testing.assert_allclose(rec.points, src.points, atol=1e-3)
    assert rec.rate == pytest.approx(30.0)
    if fmt == "openface_csv":   # OpenFace numbers landmarks: L0.., the head band L468..
        assert rec.labels[:2] == ["L0", "L1"] and rec.n_markers == 474
    else:
        assert rec.labels == dense_layout("D468")
    v, f = read_obj(tmp_path / "mesh.obj")
    np.testing.assert_allclose(v, subj.face.vertices, atol=1e-5)


def test_unknown_design_and_format_are_one_line():
    from facemotion.virtual.dense import simulate_dense, write_dense_subject

    with pytest.raises(InputError, match="design 'D9'"):
        simulate_dense("D9", shared_data=SHARED)
    subj = simulate_dense("D468", n_sentences=1, shared_data=SHARED)
    with pytest.raises(InputError, match="format 'gif'"):
        write_dense_subject(subj, "/nonexistent", "D", "gif")
