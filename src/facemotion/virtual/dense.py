"""The dense virtual talker: the virtual talker's motion at the vertices of a face mesh.

Today's users track faces densely (MediaPipe's 468 landmarks, 4-D scans of about 5,000
vertices). The dense talker is the virtual talker of :mod:`facemotion.virtual.talker` (the same
anatomical influence fields, spatially correlated tissue motion, scripts, sessions, head motion
and noise) evaluated at the vertices of the MediaPipe canonical face mesh instead of at 57
markers, so a dense study has a ground truth.

The mesh
--------
``<shared_data>/mesh/canonical_face_model.obj`` (Apache-2.0, the MediaPipe authors): 468
vertices in cm, vertex i is landmark ``L{i:03d}`` (the GRID tracks' numbering). Its axes are the
talker's head axes (x from the talker's right to left, y up, z out of the face: checked on the
eye corners L033/L263 and the nose tip L001). The 18 triangles that close the mouth (all three
corners on the inner lip contour) are dropped, so the lips are two surfaces that can part.

Head frame (the stated transform): p_mm = 10 v_cm + t, no rotation, no scaling (the mesh keeps
its own size: 89 mm between the outer eye corners). t is the least-squares translation that
brings the 14 landmarks of ``ANATOMY_LANDMARKS`` onto the talker's markers with the same
anatomical role (lip corners, lip centres, upper and lower lids, brows, nose tip, cheeks, chin;
``DenseFace.translation_mm``, about (0, 20, 18) mm for the default talker). Those 14 mesh
landmarks then centre the talker's sources (the fields' Gaussian lobes sit on the mesh's own
lips, lids and brows), and the jaw joints, head pivot and head band stay where the 57-marker
talker has them.

The lips: the jaw carries what lies below the mouth line (a smooth step 3 mm wide about the
line between the lip centres). The mesh's lips nearly touch, so on the lip band (between the
outer and inner lip contours) the step is replaced by the side of the mouth each vertex is on:
1 on the lower lip, 0 on the upper, 0.5 at the corners (``DenseFace.lip_side``).

The finer mesh
--------------
``subdivide_longest_edges`` splits the longest edge of the mesh at its midpoint, both triangles
beside it in two, until the mesh has the requested number of vertices (``FINE_VERTICES`` =
5,023, the vertex count of common 4-D scan meshes): 468 -> 5,023 vertices, with the big
triangles of the forehead, cheeks and sides split first, so vertex spacing evens out. New
vertices lie on the canonical mesh's triangles (midpoint subdivision: the surface is not
smoothed) and are labelled ``V{i:04d}``; V0000-V0467 are L000-L467. A vertex born on the lip
band takes the mean lip side of the edge it splits.

Tissue motion at the fine vertices is the Gaussian random field of the 468-vertex talker
extended by its kernel (Nystroem): T_f = K_fc K_cc^-1 T_c, exact at the 468 original vertices
(the fine talker's motion there equals the coarse talker's for the same seed), and between them
the field's conditional mean; the exponential kernel's roughness between vertices 5-10 mm apart
(a few percent of the tissue variance) is left out.

The talker
----------
:func:`simulate_dense` (designs ``D468`` and ``D5023``, ``DENSE_DESIGNS``): the virtual
talker's sources, scripts, session tempo and gains, tissue motion, noise and head motion at
``DENSE_RATE`` = 30 Hz (video), talker 2 (the S2a/S2b person) unless told, any number of
sentences, every sample tracked (a video tracker reports every landmark of a frame), the
six head-band markers H1-H6 after the vertices (the rigid reference the loading path aligns
on). Ground truth (``truth.npz``, as :mod:`facemotion.virtual.talker`'s plus the mesh's
triangles, lip
sides and split edges): the fields D (K, V, 3) and the courses s (frames, K), so with tissue
and noise off a sentence's head-frame displacements are s D exactly, and A's rank is the rank
of the fields' components D_k[:, c] (tests/test_dense_talker.py).

:func:`write_dense_subject` writes one file per sentence as TRC (default), C3D or an
OpenFace-style CSV (columns ``frame, face_id, timestamp, confidence, success, X_i, Y_i,
Z_i``; the reader calls landmark i ``L{i}``, the six head-band markers are landmarks 468-473
there), and the placed mesh as ``mesh.obj`` (mm, head frame).
"""

from __future__ import annotations

import heapq
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.virtual.designs import DENSE_DESIGNS, DESIGNS, HEAD_LABELS

#: Where the canonical face mesh is, under the shared data folder (setting ``shared_data``).
CANONICAL_MESH = Path("mesh") / "canonical_face_model.obj"
CANONICAL_VERTICES = 468
#: Vertices of the finer mesh (subdivided from the canonical one).
FINE_VERTICES = 5023
#: Talker marker (the anatomical role of ``virtual.talker._ANATOMY``) -> MediaPipe landmark.
ANATOMY_LANDMARKS = {
    "34": 291, "38": 61,        # left / right lip corner
    "36": 0, "40": 17,          # upper / lower lip centre (outer contour)
    "13": 386, "11": 159,       # left / right upper lid
    "16": 374, "15": 145,       # left / right lower lid
    "6": 334, "2": 105,         # left / right brow
    "17": 1,                    # nose tip
    "27": 426, "26": 206,       # left / right cheek, beside the nasolabial fold
    "56": 175,                  # chin (mentalis)
}
# MediaPipe lip contours, each from one mouth corner round to the other (data README).
_OUTER_LOWER = [61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291]
_OUTER_UPPER = [61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291]
_INNER_LOWER = [78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308]
_INNER_UPPER = [78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308]
_CORNERS = (61, 291, 78, 308)


def mesh_path(shared_data: str | os.PathLike | None) -> Path:
    """The canonical face mesh under ``shared_data``; InputError (one line) when it is not
    there: the dense talker cannot be made without it."""
    if shared_data is None:
        raise InputError("the dense virtual talker needs the canonical face mesh "
                         f"({CANONICAL_MESH}): set shared_data")
    p = Path(shared_data) / CANONICAL_MESH
    if not p.is_file():
        raise InputError(f"the dense virtual talker needs the canonical face mesh {p}, which "
                         "does not exist: set shared_data to the folder that holds "
                         f"{CANONICAL_MESH}")
    return p


def dense_labels(n_vertices: int) -> list[str]:
    """Vertex labels: ``L000``.. for the canonical 468, ``V0000``.. for a finer mesh."""
    if n_vertices == CANONICAL_VERTICES:
        return [f"L{i:03d}" for i in range(n_vertices)]
    return [f"V{i:04d}" for i in range(n_vertices)]


def read_canonical_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (468, 3) in cm and triangles of the canonical face, the mouth left open (the
    triangles whose corners all lie on the inner lip contour are dropped)."""
    from facemotion.io.obj import read_obj

    v, f = read_obj(path)
    if len(v) != CANONICAL_VERTICES:
        raise InputError(f"{path}: expected the {CANONICAL_VERTICES}-vertex MediaPipe canonical "
                         f"face mesh, got {len(v)} vertices")
    inner = np.zeros(len(v), dtype=bool)
    inner[_INNER_LOWER + _INNER_UPPER] = True
    mouth = inner[f].all(axis=1)
    return v, f[~mouth]


def lip_sides(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(V,) side of the mouth of each canonical vertex on the lip band: 0 upper lip, 1 lower
    lip, 0.5 the corners; NaN off the band. Contour vertices by their contour, the band's
    middle vertices by their height against the mouth-corner line (as the lip model does)."""
    from facemotion.lips.mesh import INNER_RING, OUTER_RING, lip_band

    band = np.unique(triangles[lip_band(triangles, OUTER_RING, INNER_RING)])
    side = np.full(len(vertices), np.nan)
    upper = set(_OUTER_UPPER[1:-1] + _INNER_UPPER[1:-1])
    lower = set(_OUTER_LOWER[1:-1] + _INNER_LOWER[1:-1])
    y_corners = float(np.mean(vertices[list(_CORNERS), 1]))
    for v in band:
        v = int(v)
        side[v] = (0.5 if v in _CORNERS else 0.0 if v in upper else 1.0 if v in lower
                   else 0.0 if vertices[v, 1] > y_corners else 1.0)
    return side


def subdivide_longest_edges(vertices: np.ndarray, triangles: np.ndarray, n_vertices: int,
                            values: np.ndarray | None = None):
    """Split the longest edge at its midpoint (and the one or two triangles beside it in two,
    keeping their orientation) until there are ``n_vertices`` vertices.

    values: (V,) per-vertex values carried to new vertices as the mean of the edge's two ends.
    Returns (vertices, triangles, values, parents): parents (n_vertices, 2) holds the two
    vertices of the edge each new vertex split (-1 for the original ones). Deterministic: ties
    in length go to the edge with the smaller vertex indices.
    """
    V = [np.asarray(p, dtype=float) for p in vertices]
    if n_vertices < len(V):
        raise InputError(f"subdivision: {n_vertices} vertices requested, the mesh already has "
                         f"{len(V)}")
    vals = None if values is None else list(np.asarray(values, dtype=float))
    tris: dict[int, tuple[int, int, int]] = {t: tuple(int(i) for i in tri)
                                             for t, tri in enumerate(triangles)}
    edge_tris: dict[tuple[int, int], set[int]] = {}

    def key(a: int, b: int) -> tuple[int, int]:
        return (a, b) if a < b else (b, a)

    def add(t: int, tri: tuple[int, int, int]) -> None:
        tris[t] = tri
        for i in range(3):
            edge_tris.setdefault(key(tri[i], tri[(i + 1) % 3]), set()).add(t)

    heap: list[tuple[float, int, int]] = []

    def push(e: tuple[int, int]) -> None:
        heapq.heappush(heap, (-float(np.sum((V[e[0]] - V[e[1]]) ** 2)), e[0], e[1]))

    for t, tri in list(tris.items()):
        add(t, tri)
    for e in edge_tris:
        push(e)
    parents = [(-1, -1)] * len(V)
    next_t = len(tris)
    while len(V) < n_vertices:
        _, a, b = heapq.heappop(heap)
        e = (a, b)
        if e not in edge_tris:        # split already
            continue
        m = len(V)
        V.append(0.5 * (V[a] + V[b]))
        if vals is not None:
            vals.append(0.5 * (vals[a] + vals[b]))
        parents.append(e)
        for t in sorted(edge_tris.pop(e)):
            tri = tris.pop(t)
            for i in range(3):
                k = key(tri[i], tri[(i + 1) % 3])
                if k != e:
                    edge_tris[k].discard(t)
            i = next(i for i in range(3) if {tri[i], tri[(i + 1) % 3]} == {a, b})
            p, q, c = tri[i], tri[(i + 1) % 3], tri[(i + 2) % 3]   # edge p->q, apex c
            add(t, (p, m, c))
            add(next_t, (m, q, c))
            next_t += 1
            push(key(m, c))
        push(key(a, m))
        push(key(m, b))
    tri_out = np.array([tris[t] for t in sorted(tris)], dtype=np.int64)
    return (np.array(V), tri_out, None if vals is None else np.array(vals),
            np.array(parents, dtype=np.int64))


@dataclass
class DenseFace:
    """The mesh placed in a talker's head frame (mm)."""

    labels: list[str]
    vertices: np.ndarray          # (V, 3) mm, head frame
    triangles: np.ndarray         # (T, 3)
    lip_side: np.ndarray          # (V,) 0 upper lip, 1 lower lip, 0.5 corners, NaN elsewhere
    translation_mm: np.ndarray    # t of p_mm = 10 v_cm + t
    parents: np.ndarray           # (V, 2) split edge of each added vertex, -1 for canonical

    @property
    def n(self) -> int:
        return len(self.labels)

    def anatomy(self, talker_anatomy: np.ndarray) -> np.ndarray:
        """The talker's (57, 3) source centres with the ``ANATOMY_LANDMARKS`` roles moved to
        the mesh's own landmarks (what :func:`facemotion.virtual.talker.influence_fields` reads)."""
        a = np.array(talker_anatomy, dtype=float, copy=True)
        for marker, vertex in ANATOMY_LANDMARKS.items():
            a[int(marker) - 1] = self.vertices[vertex]
        return a


def dense_face(path: str | os.PathLike, talker_anatomy: np.ndarray,
               n_vertices: int = CANONICAL_VERTICES) -> DenseFace:
    """The canonical mesh at ``path`` in the head frame of a talker whose markers (the
    57-marker layout, mm) are ``talker_anatomy``; subdivided to ``n_vertices`` if more than
    468. See the module notes for the transform."""
    v_cm, tri = read_canonical_mesh(path)
    side = lip_sides(v_cm, tri)
    lm = list(ANATOMY_LANDMARKS.values())
    target = np.asarray(talker_anatomy, dtype=float)[[int(m) - 1 for m in ANATOMY_LANDMARKS]]
    t = target.mean(axis=0) - 10.0 * v_cm[lm].mean(axis=0)   # least-squares translation
    v = 10.0 * v_cm + t
    parents = np.full((len(v), 2), -1, dtype=np.int64)
    if n_vertices != CANONICAL_VERTICES:
        v, tri, side, parents = subdivide_longest_edges(v, tri, n_vertices, side)
    return DenseFace(dense_labels(len(v)), v, tri, side, t, parents)


def write_obj(path: str | os.PathLike, face: DenseFace) -> bytes:
    """The placed mesh as Wavefront OBJ text (mm, head frame; vertex i is ``face.labels[i]``),
    returned as bytes for an atomic write."""
    from facemotion.io.obj import obj_bytes

    return obj_bytes(face.vertices, face.triangles,
                     f"facemotion dense virtual talker: {face.n} vertices, mm, head frame; "
                     f"vertex i is {face.labels[0][0]}{{i}}")


# ------------------------------------------------------------------------------ the talker

#: Frame rate of the dense talker (video trackers: MediaPipe, OpenFace).
DENSE_RATE = 30.0


def dense_design_vertices(design: str) -> int:
    """Vertices of a dense design; InputError (one line) for a name that is not one."""
    if design not in DENSE_DESIGNS:
        raise InputError(f"dense virtual talker design {design!r} unknown (use one of "
                         f"{', '.join(DENSE_DESIGNS)})")
    return DESIGNS[design].vertices


def dense_layout(design: str) -> list[str]:
    """Labels of a dense design's files: the vertices, then the six head-band markers."""
    return dense_labels(dense_design_vertices(design)) + list(HEAD_LABELS)


def tissue_extension(coarse: np.ndarray, fine: np.ndarray,
                     length_mm: float | None = None) -> np.ndarray:
    """M (V_f, V_c) = K_fc K_cc^-1 for the exponential kernel exp(-|p - p'| / length): the
    conditional mean of a Gaussian random field at ``fine`` given its values at ``coarse``
    (Nystroem extension). Rows of fine points that are coarse points are unit rows."""
    import scipy.linalg

    from facemotion.virtual.talker import TISSUE_LENGTH_MM

    length_mm = TISSUE_LENGTH_MM if length_mm is None else length_mm
    c, f = np.asarray(coarse, float), np.asarray(fine, float)
    Kcc = np.exp(-np.linalg.norm(c[:, None] - c[None], axis=-1) / length_mm)
    Kcf = np.exp(-np.linalg.norm(c[:, None] - f[None], axis=-1) / length_mm)
    return scipy.linalg.solve(Kcc, Kcf, assume_a="pos").T


def simulate_dense(design: str = "D468", seed: int = 0, n_sentences: int = 40, *,
                   shared_data: str | os.PathLike | None = None,
                   talker_seed: int | None = None, rate: float = DENSE_RATE,
                   sentence_duration: tuple[float, float] = (1.5, 4.0),
                   head_rotation_deg: float = 1.5, head_translation_mm: float = 2.0,
                   noise_mm: float | None = None, tissue_rms_mm: float | None = None):
    """The dense virtual talker (see the module notes): a ``SimulatedSubject`` with one
    ``Recording`` per sentence (the mesh's vertices, then the head band H1-H6) and its truth.

    The motion is the virtual talker's, q_v(t) = n_v + sum_k s_k(t) D_k(n_v) + T(n_v, t) +
    e_v(t), then the rigid head motion (:mod:`facemotion.virtual.talker`), with the sources' fields
    evaluated at the placed mesh (lip band: ``DenseFace.lip_side``) and the tissue field T on
    the 468 canonical vertices (extended by the kernel to a finer mesh). Sentences perform the
    corpus' scripts (``virtual.talker.sentence_script``); every sample is tracked (a video tracker
    reports all landmarks of a frame). noise_mm, tissue_rms_mm: default the virtual
    talker's. Deterministic by (design, seed, talker_seed); for the same arguments the
    noise-free motion of D5023 at V0000-V0467 equals D468's.
    """
    from facemotion.io.recording import Recording
    from facemotion.virtual import talker as synth

    n_vertices = dense_design_vertices(design)
    n = int(n_sentences)
    if n < 1:
        raise InputError(f"dense virtual talker {design}: n_sentences must be >= 1, got "
                         f"{n_sentences}")
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"dense virtual talker {design}: rate must be positive, got {rate}")
    noise_mm = synth.NOISE_3D_RMS_MM if noise_mm is None else float(noise_mm)
    tissue_rms_mm = synth.TISSUE_RMS_MM if tissue_rms_mm is None else float(tissue_rms_mm)
    if min(noise_mm, tissue_rms_mm, head_rotation_deg, head_translation_mm) < 0:
        raise InputError(f"dense virtual talker {design}: noise_mm, tissue_rms_mm, "
                         "head_rotation_deg and head_translation_mm must be >= 0")
    lo, hi = (float(v) for v in sentence_duration)
    ts = DESIGNS[design].talker if talker_seed is None else int(talker_seed)
    talker = synth.make_talker(ts)
    face = dense_face(mesh_path(shared_data), talker.anatomy, n_vertices)
    D = synth.influence_fields(face.vertices, face.anatomy(talker.anatomy), face.lip_side)
    D *= talker.strengths[:, None, None]
    coarse = face.vertices[:CANONICAL_VERTICES]
    M = None if face.n == CANONICAL_VERTICES else tissue_extension(coarse, face.vertices)
    labels = face.labels + list(synth.HEAD_LABELS)
    rng = np.random.default_rng([seed, 31, ts])
    session = synth.Session(
        labels=labels, rest=np.concatenate([face.vertices, talker.head_band]), fields=D,
        tissue=synth.tissue_factor(coarse), rate=rate, duration=(lo, hi),   # W W^T = K_cc
        tempo=1.0 + rng.uniform(-synth.SESSION_TEMPO, synth.SESSION_TEMPO),
        noise_axis=noise_mm / np.sqrt(3.0), tissue_rms_mm=tissue_rms_mm,
        rot_rms=np.deg2rad(head_rotation_deg), head_translation_mm=head_translation_mm)
    recs, parts = [], []
    for s in range(n):
        courses, tempo = synth.perform_sentence(session, s, rng)
        pts = _dense_points(session, courses, rng, M, face.n,
                            np.random.default_rng([seed, 32, ts, s]))
        motion = synth.head_motion(session, courses.shape[0], rng)
        recs.append(Recording(list(labels), synth.move_head(pts, motion), rate,
                              f"{design}_s{s + 1:02d}"))
        parts.append({"courses": courses, "head": motion, "tempo": tempo})
    per_sentence = synth._sentence_truth(parts)
    names = [r.source for r in recs]
    truth = {
        "labels": np.array(labels), "neutral": session.rest,
        "anatomy": face.anatomy(talker.anatomy), "sources": np.array(synth.SOURCES),
        "fields": D, "strengths": talker.strengths, "names": np.array(names),
        "script_index": np.arange(n), **per_sentence, "head_pivot": synth.HEAD_PIVOT.copy(),
        "missing": np.zeros((int(per_sentence["sentence_frames"].sum()), len(labels)), bool),
        "noise_per_axis_mm": np.array(session.noise_axis),
        "tissue_rms_mm": np.array(tissue_rms_mm),
        "tissue_length_mm": np.array(synth.TISSUE_LENGTH_MM),
        "rate": np.array(float(rate)), "talker_seed": np.array(ts), "seed": np.array(seed),
        "triangles": face.triangles, "lip_side": face.lip_side,
        "mesh_translation_mm": face.translation_mm, "parents": face.parents,
    }
    subject = synth.SimulatedSubject(design, recs, names, list(synth.HEAD_LABELS), truth)
    subject.face = face
    return subject


def _dense_points(session, courses: np.ndarray, rng: np.random.Generator,
                  extension: np.ndarray | None, V: int, nrng: np.random.Generator
                  ) -> np.ndarray:
    """Every vertex and head-band marker (F, V + 6, 3) in the head frame: rest + sources'
    fields + tissue (on the canonical vertices, extended to the mesh) + noise (from ``nrng``,
    vertex-major)."""
    from facemotion.virtual import talker as synth

    F, K = courses.shape
    onset = synth._onset(F, session.rate)[:, None, None]
    # tissue on the canonical vertices (smooth in time, per axis), extended to the mesh
    z = synth._smooth_noise(rng, (F, CANONICAL_VERTICES, 3), session.rate, synth.TISSUE_TIME_S,
                            1.0)
    tissue = np.matmul(session.tissue, z) * (session.tissue_rms_mm * onset)
    if extension is not None:
        tissue = np.matmul(extension, tissue)
    n_labels = len(session.labels)
    pts = np.broadcast_to(session.rest, (F, n_labels, 3)).copy()
    pts[:, :V] += (courses @ session.fields.reshape(K, -1)).reshape(F, V, 3) + tissue
    # noise drawn vertex-major, so the first 468 vertices' noise does not depend on V
    pts[:, V:] += nrng.normal(0.0, session.noise_axis, (F, n_labels - V, 3))
    pts[:, :V] += nrng.normal(0.0, session.noise_axis, (V, F, 3)).transpose(1, 0, 2)
    return pts


def write_dense_subject(subject, out_dir: str | os.PathLike, subject_id: str,
                        fmt: str = "trc") -> list[Path]:
    """Write a dense talker's sentences as ``{subject_id}_sNN.{trc,c3d,csv}`` in
    ``out_dir`` (each file written whole, then renamed) and the placed mesh as ``mesh.obj``;
    returns the recording paths. The ground truth is
    :func:`facemotion.virtual.talker.truth_npz_bytes`.
    """
    from facemotion.io.atomic import atomic_write_bytes
    from facemotion.io.registry import get_format

    formats = dict(DESIGNS[DENSE_DESIGNS[0]].formats)  # every dense design: the same formats
    if fmt not in formats:
        raise InputError(f"dense virtual talker: format {fmt!r} cannot be written (use one of "
                         f"{', '.join(formats)})")
    writer = get_format(fmt).write
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, rec in enumerate(subject.recordings):
        p = out / f"{subject_id}_s{i + 1:02d}.{formats[fmt]}"
        writer(p, rec)
        paths.append(p)
    atomic_write_bytes(out / "mesh.obj", write_obj(out / "mesh.obj", subject.face))
    return paths
