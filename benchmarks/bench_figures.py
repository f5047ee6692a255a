"""Figure rendering times: region maps (57 markers, and 468 landmarks on a grid or on the face
mesh) in PNG only (the default) and PNG + PDF, and animation frames (against the same
frames drawn by matplotlib's artists, in the same run).

    python benchmarks/bench_figures.py [--repeats N] [--animation-only]

The faces are the canonical face mesh's vertices (../shared/data/mesh, cm -> mm) and a 57-vertex
subset of them; the maps show smooth planted coefficient fields with shallow negative
subregions, k = 10 panels. Medians of N interleaved repetitions, one thread; wall time for the
maps, CPU time for the animation frames.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from facemotion.plots.animation import FaceAnimation  # noqa: E402
from facemotion.plots.face_mesh import read_face_mesh  # noqa: E402
from facemotion.plots.regions import plot_region_maps  # noqa: E402
from facemotion.plots.save import figure_bytes  # noqa: E402


def shared_data() -> Path:
    env = os.environ.get("FACEMOTION_SHARED_DATA")
    return Path(env) if env else ROOT.parent / "shared" / "data"


def planted_X(neutral: np.ndarray, labels: list[str], k: int = 10) -> pd.DataFrame:
    """k main markers spread over the face; each one's field a smooth bump, slightly negative
    far away (as estimated regions are)."""
    rng = np.random.default_rng(0)
    mains = sorted(rng.choice(len(labels), k, replace=False).tolist())
    sec = [j for j in range(len(labels)) if j not in mains]
    span = np.ptp(neutral[:, :2], axis=0).mean()
    X = np.array([np.exp(-((neutral[sec, :2] - neutral[m, :2]) ** 2).sum(1) / (0.05 * span ** 2))
                  - 0.12 for m in mains])
    return pd.DataFrame(X, index=[labels[m] for m in mains], columns=[labels[j] for j in sec])


def time_region_map(neutral, labels, X, mesh, formats) -> float:
    t = time.perf_counter()
    fig = plot_region_maps(neutral, labels, X, mesh=mesh)
    for i, f in enumerate(formats):
        figure_bytes(fig, f)
        if i == 0 and len(formats) > 1:
            fig.set_layout_engine("none")  # as provenance.save_figure does
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--animation-only", action="store_true", help="skip the region maps")
    args = ap.parse_args()
    mesh = read_face_mesh(shared_data() / "mesh" / "canonical_face_model.obj")
    neutral468 = 10.0 * mesh.vertices
    labels468 = mesh.labels
    idx57 = np.linspace(0, 467, 57).round().astype(int)
    neutral57, labels57 = neutral468[idx57], [labels468[i] for i in idx57]
    cases = {
        "57 markers, grid, png": (neutral57, labels57, None, ("png",)),
        "57 markers, grid, png+pdf": (neutral57, labels57, None, ("png", "pdf")),
        "468 landmarks, grid, png": (neutral468, labels468, None, ("png",)),
        "468 landmarks, mesh, png": (neutral468, labels468, mesh, ("png",)),
        "468 landmarks, mesh, png+pdf": (neutral468, labels468, mesh, ("png", "pdf")),
    }
    Xs = {name: planted_X(c[0], c[1]) for name, c in cases.items()}
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(0 if args.animation_only else args.repeats):
        for name, (neutral, labels, m, formats) in cases.items():
            times[name].append(time_region_map(neutral, labels, Xs[name], m, formats))
    if not args.animation_only:
        print(f"region maps, k = 10 panels, median of {args.repeats}:")
        for name, ts in times.items():
            print(f"  {name:32s} {statistics.median(ts):6.2f} s")
    # animation: 60 frames of a 57-marker face, drawn as the workflow draws them (FaceAnimation
    # .frame) and by matplotlib's artists (frame_reference: the renderer frame replaced),
    # interleaved, CPU time
    rng = np.random.default_rng(1)
    T = 60
    motion = np.sin(np.arange(T)[:, None, None] / 5.0) * rng.normal(size=(1, 57, 3))
    anim = FaceAnimation(neutral57, motion, 0.8 * motion, labels57, labels57[:10])
    frame_ms: dict[str, list[float]] = {"frame": [], "frame_reference": []}
    for _ in range(args.repeats):
        for name in frame_ms:
            draw = getattr(anim, name)
            t = time.process_time()
            for i in range(T):
                draw(i, f"frame {i + 1}")
            frame_ms[name].append(1000 * (time.process_time() - t) / T)
    new, ref = (statistics.median(v) for v in frame_ms.values())
    print(f"animation frames (57 markers, 800 x 460 px, CPU, median of {args.repeats}): "
          f"{new:.1f} ms/frame; matplotlib's artists {ref:.1f} ms/frame ({ref / new:.1f}x)")

if __name__ == "__main__":
    main()
