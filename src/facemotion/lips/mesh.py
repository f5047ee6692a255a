"""The triangular thin-shell lip mesh of Basu & Pentland (1997): geometry, roles, validation.

Two meshes are built here:

* `parametric_lip_mesh`: a synthetic lip of realistic size (about 50 mm wide, curved round the
  teeth in z), made of closed rings from the outer lip contour to the inner one, plus a thin
  strip from the top of the lips back into the mouth, grounded at the strip's far end (paper
  Sec. 2.4). The default (32 nodes round, 5 rings, an 11 x 4 strip, 4 grounded nodes) has the
  paper's counts (Secs. 2.1, 4.1): 204 nodes, 612 DOF, 336 triangles, 600 free DOF.
* `canonical_lip_mesh`: the lip band of the MediaPipe canonical face mesh (80 vertices, 120
  triangles between the inner and outer lip contours; the 18 triangles that close the mouth are
  dropped), plus an extruded mouth strip.

Node roles: 'outer' (outer contour), 'lip' (between the contours), 'inner' (inner contour, the
lip ridge), 'strip' (inside the mouth), 'fixed' (grounded, at the strip's far end). Element
kinds: 'lip',
'ridge' (touching the inner contour from the lip side; twice as stiff in the paper), 'strip'
(soft). Node parts: 'upper', 'lower', 'corner' (mouth corners), used to fit the lip planes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from facemotion.errors import InputError
from facemotion.io.obj import read_obj

ROLES = ("outer", "lip", "inner", "strip", "fixed")


KINDS = ("lip", "ridge", "strip")


BAND_ROLES = ("outer", "lip", "inner")


# MediaPipe lip contours (data README), each from one mouth corner round to the other.
OUTER_LOWER = [61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291]


OUTER_UPPER = [61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291]


INNER_LOWER = [78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308]


INNER_UPPER = [78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308]


def _ring(lower: list[int], upper: list[int]) -> list[int]:
    """Closed loop: along the lower contour, then back along the upper one."""
    return lower + upper[-2:0:-1]


OUTER_RING = _ring(OUTER_LOWER, OUTER_UPPER)


INNER_RING = _ring(INNER_LOWER, INNER_UPPER)


@dataclass
class LipMesh:
    """A lip mesh. nodes (N, 3) in mm; triangles (T, 3) node indices; fixed node indices.

    role (N,) and part (N,) are strings per node; element_kind (T,) per triangle; labels (N,)
    unique node names ('L017' for canonical-mesh vertices, 'n000' for generated nodes).
    """

    nodes: np.ndarray
    triangles: np.ndarray
    fixed: np.ndarray
    role: np.ndarray
    part: np.ndarray
    element_kind: np.ndarray
    labels: list[str]
    name: str = "lip mesh"
    _index: dict[str, int] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.nodes = np.asarray(self.nodes, dtype=float)
        self.triangles = np.asarray(self.triangles)
        self.fixed = np.unique(np.asarray(self.fixed, dtype=int))
        self.role = np.asarray(self.role, dtype=object)
        self.part = np.asarray(self.part, dtype=object)
        self.element_kind = np.asarray(self.element_kind, dtype=object)
        self.labels = [str(s) for s in self.labels]
        self._validate()
        self._index = {label: i for i, label in enumerate(self.labels)}

    # -- validation -------------------------------------------------------------------------
    def _validate(self) -> None:
        name = self.name
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3:
            raise InputError(f"{name}: nodes must be (N, 3), got shape {self.nodes.shape}")
        n = self.nodes.shape[0]
        if not np.all(np.isfinite(self.nodes)):
            bad = int(np.where(~np.isfinite(self.nodes).all(axis=1))[0][0])
            raise InputError(f"{name}: node {bad} has a non-finite coordinate")
        if self.triangles.ndim != 2 or self.triangles.shape[1] != 3:
            raise InputError(f"{name}: triangles must be (T, 3), got shape "
                             f"{self.triangles.shape}")
        if not np.issubdtype(self.triangles.dtype, np.integer):
            raise InputError(f"{name}: triangle node indices must be integers")
        self.triangles = self.triangles.astype(np.int64)
        for what, arr, size in (("role", self.role, n), ("part", self.part, n),
                                ("labels", np.asarray(self.labels), n),
                                ("element_kind", self.element_kind, len(self.triangles))):
            if len(arr) != size:
                raise InputError(f"{name}: {what} has {len(arr)} entries, expected {size}")
        out = np.where((self.triangles < 0) | (self.triangles >= n))
        if len(out[0]):
            t = int(out[0][0])
            raise InputError(f"{name}: triangle {t} (nodes {self.triangles[t].tolist()}) "
                             f"has a node index outside 0..{n - 1}")
        for t, tri in enumerate(self.triangles):
            if len(set(tri.tolist())) < 3:
                raise InputError(f"{name}: triangle {t} (nodes {tri.tolist()}) repeats a node")
        key = np.sort(self.triangles, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            dup = key[first[counts > 1][0]]
            ts = np.where((key == dup).all(axis=1))[0].tolist()
            raise InputError(f"{name}: triangles {ts} are duplicates (nodes {dup.tolist()})")
        areas = triangle_areas(self.nodes, self.triangles)
        edges = np.linalg.norm(self.nodes[self.triangles] - self.nodes[np.roll(
            self.triangles, 1, axis=1)], axis=2)
        scale = float(np.median(edges)) if edges.size else 1.0
        degenerate = np.where(areas <= 1e-9 * scale ** 2)[0]
        if len(degenerate):
            t = int(degenerate[0])
            raise InputError(f"{name}: triangle {t} (nodes {self.triangles[t].tolist()}) is "
                             f"degenerate (area {areas[t]:.3g} mm^2)")
        if len(self.fixed) and (self.fixed.min() < 0 or self.fixed.max() >= n):
            raise InputError(f"{name}: fixed node index outside 0..{n - 1}")
        bad_roles = set(self.role.tolist()) - set(ROLES)
        if bad_roles:
            raise InputError(f"{name}: unknown node roles {sorted(bad_roles)} "
                             f"(allowed {list(ROLES)})")
        bad_kinds = set(self.element_kind.tolist()) - set(KINDS)
        if bad_kinds:
            raise InputError(f"{name}: unknown element kinds {sorted(bad_kinds)} "
                             f"(allowed {list(KINDS)})")
        if len(set(self.labels)) != len(self.labels):
            dup = sorted({s for s in self.labels if self.labels.count(s) > 1})
            raise InputError(f"{name}: duplicate node labels {dup[:5]}")

    # -- accessors --------------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    @property
    def free_nodes(self) -> np.ndarray:
        """Indices of the nodes that are not fixed, ascending."""
        return np.setdiff1d(np.arange(self.n_nodes), self.fixed)

    @property
    def band_nodes(self) -> np.ndarray:
        """Indices of the lip-band nodes (outer, lip, inner), the nodes one can see."""
        return np.where(np.isin(self.role, BAND_ROLES))[0]

    def index(self, label: str) -> int:
        try:
            return self._index[str(label)]
        except KeyError:
            raise InputError(f"{self.name}: {label!r} is not a node of the lip mesh "
                             f"({self.n_nodes} nodes: {', '.join(self.labels[:5])}, ...)"
                             ) from None

    def indices(self, labels: list[str]) -> np.ndarray:
        return np.array([self.index(s) for s in labels], dtype=int)

    def stiffness_factors(self, ridge_factor: float = 2.0,
                          strip_factor: float = 0.5) -> np.ndarray:
        """Per-triangle multiplier of Young's modulus from the element kinds."""
        f = np.ones(self.n_triangles)
        f[self.element_kind == "ridge"] = ridge_factor
        f[self.element_kind == "strip"] = strip_factor
        return f

    def with_nodes(self, nodes: np.ndarray, name: str | None = None) -> LipMesh:
        """The same topology with new node positions."""
        return LipMesh(np.asarray(nodes, dtype=float).copy(), self.triangles.copy(),
                       self.fixed.copy(), self.role.copy(), self.part.copy(),
                       self.element_kind.copy(), list(self.labels), name or self.name)


def triangle_areas(nodes: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    p = nodes[triangles]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


# -- parametric mesh ------------------------------------------------------------------------
def _ring_quads(ring_a: np.ndarray, ring_b: np.ndarray, theta: np.ndarray) -> list[list[int]]:
    """Two triangles per quad between two closed rings; diagonals mirror-symmetric in x and y."""
    n = len(ring_a)
    tris = []
    for k in range(n):
        k1 = (k + 1) % n
        a, b, c, d = ring_a[k], ring_a[k1], ring_b[k], ring_b[k1]
        mid = theta[k] + np.pi / n
        if np.cos(mid) * np.sin(mid) > 0:
            tris += [[a, b, d], [a, d, c]]
        else:
            tris += [[a, b, c], [b, d, c]]
    return tris


def _strip_quads(row_a: np.ndarray, row_b: np.ndarray, x: np.ndarray) -> list[list[int]]:
    """Two triangles per quad between two open rows; diagonals mirror-symmetric about x = 0."""
    tris = []
    for c in range(len(row_a) - 1):
        a, b, p, q = row_a[c], row_a[c + 1], row_b[c], row_b[c + 1]
        if x[c] + x[c + 1] < 0:
            tris += [[a, b, q], [a, q, p]]
        else:
            tris += [[a, b, p], [b, q, p]]
    return tris


def parametric_lip_mesh(n_around: int = 32, n_rings: int = 5, strip_width: int = 11,
                        strip_rows: int = 4, width: float = 50.0, upper_height: float = 11.0,
                        lower_height: float = 12.0, inner_width: float = 42.0,
                        opening: float = 3.0, jaw_radius: float = 45.0,
                        bulge: float = 4.0, strip_depth: float = 4.0,
                        strip_rise: float = 1.0, grounded: int = 4) -> LipMesh:
    """A synthetic lip mesh (mm): x to the talker's left (image right), y up, z forward.

    Rings run from the outer lip contour (ring 0) to the inner contour (ring n_rings - 1). Node k
    of every ring sits at angle 2 pi k / n_around from the corner at +x (k = 0), so tracked
    points can be chosen at the same angle on the outer and inner contours. As in the paper
    (Sec. 2.4), a thin strip of `strip_width` x `strip_rows` nodes runs from the middle of the
    upper lip's inner contour back into the mouth (`strip_depth` mm back and `strip_rise` mm up
    per row). `grounded` nodes of its far row are fixed, spread evenly and mirror-symmetric
    (both ends always; `strip_width` fixes the whole row). The defaults give the paper's counts
    (Sec. 2.1): 32 x 5 + 11 x 4 = 204 nodes (612 DOF) and 2 x 32 x 4 + 2 x 10 x 4 = 336
    triangles; and with 4 nodes grounded, 612 - 12 = 600 free DOF, the "600 columns" of P
    (Sec. 4.1). The paper is not consistent here: Sec. 2.3 says two nodes (6 DOF) must be
    grounded (the six rigid-body motions of a 3-D body), Sec. 2.4 fixes "the nodes at the far
    end of this strip" and Sec. 4.1 counts 600 columns, which is 4 nodes (12 DOF) of 204.
    Our reading: 4 nodes at the far end of the strip are grounded, which gives the 600.
    """
    _check_mesh_settings(n_around, n_rings, strip_width, strip_rows, grounded)
    theta = 2 * np.pi * np.arange(n_around) / n_around
    c, s = np.cos(theta), np.sin(theta)
    outer = np.column_stack([width / 2 * c, np.where(s >= 0, upper_height, lower_height) * s])
    inner = np.column_stack([inner_width / 2 * c, opening / 2 * s])
    nodes, role = [], []
    for r in range(n_rings):
        frac = r / (n_rings - 1)
        xy = (1 - frac) * outer + frac * inner
        # curved round the teeth, plus the vermilion bulge (largest mid-lip, least at corners)
        z = -xy[:, 0] ** 2 / (2 * jaw_radius) + bulge * np.sin(np.pi * 0.8 * frac) * (
            1 - 0.6 * c ** 2)
        nodes.append(np.column_stack([xy, z]))
        role += ["outer" if r == 0 else "inner" if r == n_rings - 1 else "lip"] * n_around
    rings = np.arange(n_rings)[:, None] * n_around + np.arange(n_around)
    tris, kinds = [], []
    for r in range(n_rings - 1):
        q = _ring_quads(rings[r], rings[r + 1], theta)
        tris += q
        kinds += ["lip" if r < n_rings - 2 else "ridge"] * len(q)
    # the strip: columns at the inner-contour nodes centred on the top of the upper lip
    top = n_around // 4
    cols = rings[-1][top + (strip_width // 2) - np.arange(strip_width)]   # from -x... to +x
    cols = cols[np.argsort(nodes[-1][cols - rings[-1][0], 0])]
    base = np.vstack(nodes)[cols]
    n = n_rings * n_around
    prev = cols
    for j in range(1, strip_rows + 1):
        p = base.copy()
        p[:, 0] *= 1 - 0.05 * j
        p[:, 1] += strip_rise * j
        p[:, 2] -= strip_depth * j
        nodes.append(p)
        cur = n + np.arange(strip_width)
        n += strip_width
        q = _strip_quads(prev, cur, base[:, 0])
        tris += q
        kinds += ["strip"] * len(q)
        row_role = np.full(strip_width, "strip", dtype=object)
        if j == strip_rows:
            row_role[_grounded_columns(strip_width, grounded)] = "fixed"
        role += list(row_role)
        prev = cur
    nodes = np.vstack(nodes)
    part_ring = np.where(np.abs(s) < 1e-9, "corner", np.where(s > 0, "upper", "lower"))
    role = np.array(role, dtype=object)
    part = np.concatenate([np.tile(part_ring, n_rings),
                           np.full(strip_width * strip_rows, "strip")]).astype(object)
    labels = [f"n{i:03d}" for i in range(len(nodes))]
    fixed = np.where(role == "fixed")[0]
    return LipMesh(nodes, np.array(tris), fixed, role, part,
                   np.array(kinds, dtype=object), labels, name="parametric lip mesh")


def _check_mesh_settings(n_around: int, n_rings: int, strip_width: int, strip_rows: int,
                         grounded: int) -> None:
    """The counts ``parametric_lip_mesh`` can build: one line naming the one at fault."""
    if n_around < 8 or n_around % 4:
        raise InputError(f"parametric_lip_mesh: n_around must be a multiple of 4 and >= 8, "
                         f"got {n_around}")
    if n_rings < 2:
        raise InputError(f"parametric_lip_mesh: n_rings must be >= 2, got {n_rings}")
    if strip_rows < 1:
        raise InputError(f"parametric_lip_mesh: strip_rows must be >= 1, got {strip_rows}")
    if strip_width < 3 or strip_width % 2 == 0 or strip_width > n_around // 2 + 1:
        raise InputError(f"parametric_lip_mesh: strip_width must be odd, >= 3 and at most "
                         f"{n_around // 2 + 1} (the upper lip), got {strip_width}")
    if not 2 <= grounded <= strip_width or (grounded % 2 and grounded != strip_width):
        raise InputError(f"parametric_lip_mesh: grounded must be even (mirror-symmetric), "
                         f">= 2 and at most strip_width ({strip_width}), or strip_width "
                         f"itself, got {grounded}")


def _grounded_columns(width: int, grounded: int) -> np.ndarray:
    """Columns of the far strip row that are grounded: `grounded` of `width`, evenly spread,
    both ends included, mirror-symmetric (column c and width - 1 - c together)."""
    if grounded >= width:
        return np.arange(width)
    half = np.round(np.linspace(0, width - 1, grounded)[:grounded // 2]).astype(int)
    return np.unique(np.concatenate([half, width - 1 - half]))


def extents(nodes: np.ndarray) -> np.ndarray:
    """Bounding-box size (3,) of nodes (N, 3) along x, y, z."""
    nodes = np.asarray(nodes, dtype=float)
    return nodes.max(axis=0) - nodes.min(axis=0)


# The paper's model size (Sec. 5): "2.35 units across, 2.83 units wide, and 5.05 units deep".
# Our reading: the three numbers in the printed order are the extents along the model's x, y, z
# (the paper lists axes in that order throughout; 'deep' is the depth axis z, the one a frontal
# (x-y) view cannot see). Table 1 is in these units.
PAPER_MODEL_EXTENT = (2.35, 2.83, 5.05)


def model_units_per_mm(mesh: LipMesh, extent: tuple[float, float, float] | None) -> np.ndarray:
    """Per-axis factors (3,) from the mesh's coordinates (mm) to model units: the mesh's
    bounding box (all nodes) becomes `extent` (x, y, z). None: keep mm (factors 1)."""
    if extent is None:
        return np.ones(3)
    extent = np.asarray(extent, dtype=float)
    if extent.shape != (3,) or not np.all(np.isfinite(extent)) or np.any(extent <= 0):
        raise InputError(f"model_extent: need three positive sizes (x, y, z), "
                         f"got {extent.tolist()}")
    return extent / extents(mesh.nodes)


def lip_band(triangles: np.ndarray, outer_ring: list[int] = OUTER_RING,
             inner_ring: list[int] = INNER_RING, source: str = "mesh") -> np.ndarray:
    """Indices of the triangles between the outer and inner lip contours.

    Flood fill over triangle edges that do not lie on either contour: the face splits into the
    skin outside the outer contour, the lip band, and the triangles closing the mouth; the band
    is the region bordering both contours.
    """
    def ring_edges(ring: list[int]) -> set[frozenset[int]]:
        return {frozenset((ring[i], ring[(i + 1) % len(ring)])) for i in range(len(ring))}

    outer_e, inner_e = ring_edges(outer_ring), ring_edges(inner_ring)
    edge_tris: dict[frozenset[int], list[int]] = {}
    for t, tri in enumerate(triangles):
        for i in range(3):
            edge_tris.setdefault(frozenset((int(tri[i]), int(tri[(i + 1) % 3]))), []).append(t)
    missing = [sorted(e) for e in outer_e | inner_e if e not in edge_tris]
    if missing:
        raise InputError(f"{source}: lip contour edge {missing[0]} is not an edge of the mesh")
    label = -np.ones(len(triangles), dtype=int)
    regions = []
    for seed in range(len(triangles)):
        if label[seed] >= 0:
            continue
        stack, members, touches = [seed], [], set()
        label[seed] = len(regions)
        while stack:
            t = stack.pop()
            members.append(t)
            tri = triangles[t]
            for i in range(3):
                e = frozenset((int(tri[i]), int(tri[(i + 1) % 3])))
                if e in outer_e:
                    touches.add("outer")
                    continue
                if e in inner_e:
                    touches.add("inner")
                    continue
                for u in edge_tris[e]:
                    if label[u] < 0:
                        label[u] = label[seed]
                        stack.append(u)
        regions.append((members, touches))
    band = [m for m, touch in regions if touch == {"outer", "inner"}]
    if len(band) != 1:
        raise InputError(f"{source}: expected one lip band between the contours, "
                         f"found {len(band)}")
    return np.array(sorted(band[0]), dtype=int)


def canonical_lip_mesh(obj_path: str | Path, strip_rings: int = 2, strip_depth: float = 4.0,
                       band_nodes: dict[str, np.ndarray] | None = None) -> LipMesh:
    """The lip band of the MediaPipe canonical face (OBJ in cm -> mm) plus a mouth strip.

    The band: 80 vertices, 120 triangles (the 18 mouth-closing triangles are dropped). Node
    labels are the landmark names 'L{i:03d}'. `band_nodes` optionally replaces band vertex
    positions (label -> (3,) mm), e.g. with a talker's own rest-frame landmarks. The strip is
    extruded from the inner contour: each of `strip_rings` rings steps `strip_depth` mm back
    (-z, into the mouth) and 15 % towards the mouth's centre line in y; the far ring is fixed.
    Strip nodes are labelled 'S{ring}_{landmark}'.
    """
    verts, faces = read_obj(obj_path)
    if len(verts) < 468:
        raise InputError(f"{obj_path}: expected the 468-vertex MediaPipe canonical face, "
                         f"got {len(verts)} vertices")
    verts = verts * 10.0  # cm -> mm
    band_t = lip_band(faces, source=str(obj_path))
    band_faces = faces[band_t]
    band_v = np.unique(band_faces)
    labels = [f"L{i:03d}" for i in band_v]
    pos = verts[band_v].copy()
    if band_nodes is not None:
        for j, lab in enumerate(labels):
            if lab not in band_nodes:
                raise InputError(f"band_nodes: lip landmark {lab} missing")
            pos[j] = np.asarray(band_nodes[lab], dtype=float)
    local = {int(v): j for j, v in enumerate(band_v)}
    tris = np.vectorize(local.__getitem__)(band_faces)
    outer_set, inner_set = set(OUTER_RING), set(INNER_RING)
    role = np.array(["outer" if v in outer_set else "inner" if v in inner_set else "lip"
                     for v in band_v], dtype=object)
    # parts: contour membership, middle vertices by height against the mouth-corner line
    upper = set(OUTER_UPPER[1:-1] + INNER_UPPER[1:-1])
    lower = set(OUTER_LOWER[1:-1] + INNER_LOWER[1:-1])
    corners = {61, 291, 78, 308}
    y_mid = np.mean([pos[local[v], 1] for v in corners])
    part = np.array(["corner" if v in corners else "upper" if v in upper else "lower"
                     if v in lower else ("upper" if pos[local[v], 1] > y_mid else "lower")
                     for v in band_v], dtype=object)
    n_inner_edge = np.isin(band_faces, list(inner_set)).sum(axis=1)
    kinds = np.where(n_inner_edge >= 2, "ridge", "lip").astype(object)
    # mouth strip: rings extruded from the inner contour
    ring = np.array([local[v] for v in INNER_RING])
    centre_y = pos[ring, 1].mean()
    nodes = [pos]
    prev = ring
    tris_all, kinds_all = [tris], [kinds]
    roles, parts, labs = [role], [part], list(labels)
    n = len(pos)
    theta = np.linspace(0, 2 * np.pi, len(ring), endpoint=False)
    for j in range(1, strip_rings + 1):
        p = pos[ring].copy()
        p[:, 1] = centre_y + (p[:, 1] - centre_y) * (1 - 0.15 * j)
        p[:, 2] -= strip_depth * j
        nodes.append(p)
        cur = n + np.arange(len(ring))
        n += len(ring)
        q = _ring_quads(prev, cur, theta)
        tris_all.append(np.array(q))
        kinds_all.append(np.array(["strip"] * len(q), dtype=object))
        roles.append(np.array(["fixed" if j == strip_rings else "strip"] * len(ring),
                              dtype=object))
        parts.append(np.array(["strip"] * len(ring), dtype=object))
        labs += [f"S{j}_{labels[i]}" for i in ring]
        prev = cur
    role_all = np.concatenate(roles)
    return LipMesh(np.vstack(nodes), np.vstack(tris_all), np.where(role_all == "fixed")[0],
                   role_all, np.concatenate(parts), np.concatenate(kinds_all), labs,
                   name=f"canonical lip mesh ({Path(obj_path).name})")


def __getattr__(name: str):
    """``unit_scale`` of facemotion 0.1, now :func:`model_units_per_mm` (the readers' unit_scale
    is millimetres per unit)."""
    if name == "unit_scale":
        import warnings

        warnings.warn("facemotion.lips.mesh.unit_scale is deprecated and will be removed in "
                      "facemotion 0.3; use facemotion.lips.mesh.model_units_per_mm",
                      DeprecationWarning, stacklevel=2)
        return model_units_per_mm
    raise AttributeError(f"module 'facemotion.lips.mesh' has no attribute {name!r}")
