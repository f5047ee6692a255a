"""Wavefront OBJ meshes: vertices and triangles (faces with more corners are fanned)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from facemotion.errors import InputError


# -- canonical (MediaPipe) mesh -------------------------------------------------------------
def read_obj(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (T, 3, 0-based) of a Wavefront OBJ file.

    Reads 'v' and 'f' lines; face entries may be 'a', 'a/b', 'a//c' or 'a/b/c'; negative
    indices count from the end; polygons are fan-triangulated. Other lines are ignored.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputError(f"{path}: cannot read OBJ file ({exc.strerror})") from None
    verts, faces = [], []
    for lineno, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                verts.append([float(t) for t in tok[1:4]])
                if len(verts[-1]) != 3:
                    raise ValueError("a vertex needs 3 coordinates")
            elif tok[0] == "f":
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                if len(idx) < 3:
                    raise ValueError("a face needs at least 3 vertices")
                faces += [[idx[0], idx[j], idx[j + 1]] for j in range(1, len(idx) - 1)]
        except ValueError as exc:
            raise InputError(f"{path}: line {lineno}: bad OBJ record {line.strip()!r} "
                             f"({exc})") from None
    v = np.array(verts, dtype=float).reshape(-1, 3)
    f = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise InputError(f"{path}: a face refers to a vertex outside 1..{len(v)}")
    return v, f


def obj_bytes(vertices, triangles, comment: str = "") -> bytes:
    """A mesh as Wavefront OBJ text (vertices with 6 decimals, 1-based faces), as bytes for an
    atomic write; ``comment`` becomes the first line (``# ...``)."""
    lines = [f"# {comment}"] if comment else []
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    return ("\n".join(lines) + "\n").encode()
