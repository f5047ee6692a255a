"""Synthetic dense face recordings for the benchmarks: the canonical mesh's 468 vertices moved
by smooth fields (no claim of realism; what matters is size, smoothness and known truth).

Motion of vertex v at frame f (mm):

    x_v(f) = 10 * mesh_v + sum_s w_s(v) d_s sin(2 pi f_s t + phi_s) + noise

with ``n_sources`` Gaussian bumps w_s(v) = exp(-|v - c_s|^2 / (2 sigma_s^2)) around random
vertices c_s (sigma 15-40 mm), random unit directions d_s times 1-4 mm, frequencies 0.3-4 Hz,
plus 0.05 mm Gaussian noise.  Deterministic for a seed.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from facemotion.io.obj import read_obj
from facemotion.io.recording import Recording

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("FACEMOTION_SHARED_DATA", REPO.parent / "shared" / "data"))
MESH = SHARED / "mesh" / "canonical_face_model.obj"


def mesh_vertices_mm(subdivide: int = 0) -> np.ndarray:
    """The canonical mesh's vertices in mm; ``subdivide`` rounds of edge midpoints (x ~4)."""
    v, tri = read_obj(MESH)
    v = 10.0 * v
    for _ in range(subdivide):
        e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
        e, inv = np.unique(e, axis=0, return_inverse=True)
        inv = inv.ravel()
        mid = len(v) + np.arange(len(e))
        v = np.vstack([v, 0.5 * (v[e[:, 0]] + v[e[:, 1]])])
        m01, m12, m20 = (mid[inv[k * len(tri):(k + 1) * len(tri)]] for k in range(3))
        tri = np.concatenate([np.stack([tri[:, 0], m01, m20], 1),
                              np.stack([tri[:, 1], m12, m01], 1),
                              np.stack([tri[:, 2], m20, m12], 1), np.stack([m01, m12, m20], 1)])
    return v


def dense_points(frames: int, vertices: np.ndarray, rate: float = 30.0, n_sources: int = 12,
                 noise_mm: float = 0.05, seed: int = 0, dtype=np.float64) -> np.ndarray:
    """(frames, n, 3) positions in mm; built in blocks of frames to bound temporary memory."""
    rng = np.random.default_rng(seed)
    n = len(vertices)
    centres = vertices[rng.integers(0, n, n_sources)]
    sigma = rng.uniform(15.0, 40.0, n_sources)
    W = np.exp(-((vertices[None] - centres[:, None]) ** 2).sum(-1) / (2 * sigma[:, None] ** 2))
    d = rng.standard_normal((n_sources, 3))
    d *= rng.uniform(1.0, 4.0, (n_sources, 1)) / np.linalg.norm(d, axis=1, keepdims=True)
    fields = W[:, :, None] * d[:, None, :]  # (S, n, 3)
    freq = rng.uniform(0.3, 4.0, n_sources)
    phase = rng.uniform(0, 2 * np.pi, n_sources)
    out = np.empty((frames, n, 3), dtype=dtype)
    step = max(1, 2_000_000 // (3 * n))
    for a in range(0, frames, step):
        b = min(frames, a + step)
        t = np.arange(a, b) / rate
        src = np.sin(2 * np.pi * freq[None] * t[:, None] + phase[None])  # (f, S)
        blk = vertices[None] + np.tensordot(src, fields, axes=1)
        blk += noise_mm * np.random.default_rng([seed, a]).standard_normal(blk.shape)
        out[a:b] = blk
    return out


def dense_recording(frames: int, subdivide: int = 0, rate: float = 30.0, seed: int = 0,
                    gaps_s: tuple[float, ...] = ()) -> tuple[Recording, Recording]:
    """(truth, with gaps): ``gaps_s`` long gaps (seconds) of distinct markers, spread in time."""
    v = mesh_vertices_mm(subdivide)
    pts = dense_points(frames, v, rate=rate, seed=seed)
    labels = [f"L{j:03d}" if j < 1000 else f"V{j:04d}" for j in range(len(v))]
    truth = Recording(labels, pts, rate, source=f"dense_{len(v)}x{frames}")
    gapped = pts.copy()
    rng = np.random.default_rng(seed + 1)
    markers = rng.choice(len(v), size=len(gaps_s), replace=False)
    for i, (j, g) in enumerate(zip(markers, gaps_s, strict=True)):
        length = int(round(g * rate))
        start = int((i + 0.5) * frames / max(len(gaps_s), 1)) - length // 2
        gapped[max(0, start):start + length, j] = np.nan
    return truth, Recording(labels, gapped, rate, source=truth.source)
