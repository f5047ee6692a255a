"""CPU time of drawing the default study's figures, redrawn in-process from a finished study.

    python benchmarks/bench_study_figures.py STUDY_RESULTS [--repeats N] [--baseline SRC]
        [--only NAME,...] [--out DIR]

STUDY_RESULTS: a finished study's results directory (e.g. results/paper). Each figure type is
built from the study's files as its rule builds it (the same plot functions, the data
prepared by the same package functions) and rendered to PNG bytes as ``save_figure`` renders
it; the time is CPU time (``time.process_time``) of building and rendering, summed over the
study's datasets, the data preparation left out: each figure's least time over the passes
(``--rounds`` in each of ``--repeats`` processes), as the machine's other load only adds time.

``--baseline SRC``: a ``src`` directory of another version of the package (e.g. from
``git archive main src | tar -x -C /tmp/base``): each repetition then runs this code and that
one in fresh processes, alternately (the machine's load varies), side by side. ``--out DIR``
writes each figure's PNG (of this code) for a look.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _trajectory_figure(study: Path, ds: str, held, ranking):
    """The trajectory figure of a dataset's first held-out sentence, from its table."""
    import numpy as np
    import pandas as pd

    from facemotion.plots.error_curves import plot_trajectory
    from facemotion.regions.prediction import predict

    traj = pd.read_csv(study / ds / "eval" / "trajectory_errors.tsv", sep="\t",
                       dtype={"marker": str, "requested_marker": str}, keep_default_na=False)
    marker, requested = traj["marker"][0], traj["requested_marker"][0]
    one = held.subset([0])
    j = one.labels.index(marker)
    measured = one.A[:, j].reshape(-1, 3)
    model = predict(ranking, 10, one.A)[:, j].reshape(-1, 3)
    t = np.arange(measured.shape[0]) / one.rate
    in_basis = marker in ranking.labels_in_order[:10]
    note = (None if requested == marker else f"marker {requested} requested, not in this "
            "dataset" if requested else "no marker requested: the secondary marker that "
            "moves most")
    return lambda: plot_trajectory(t, measured, model, marker=marker,
                                   sentence=one.sentences[0], k=10, in_basis=in_basis,
                                   note=note)


def _gaps_figure(study: Path, ds: str, rate: float):
    """The gap raster of a dataset: the markers' gaps of gap_report.tsv (counts and longest
    gap) placed at fixed pseudo-random times (the loaded masks are not kept)."""
    import numpy as np
    import pandas as pd

    from facemotion.plots.gaps import plot_gaps

    report = pd.read_csv(study / ds / "data" / "gap_report.tsv", sep="\t",
                         dtype={"marker": str})
    sent = pd.read_csv(study / ds / "data" / "sentences.tsv", sep="\t")
    frames = int(report["frames"].max())
    filled = np.zeros((frames, len(report)), dtype=bool)
    rng = np.random.default_rng(0)
    for j, row in enumerate(report.itertuples()):
        for g in range(int(row.n_gaps)):
            n = int(row.longest_gap_frames) if g == 0 else 1 + int(rng.integers(10))
            a = int(rng.integers(0, frames - n))
            filled[a:a + n, j] = True
    starts = np.cumsum([0.0, *sent["duration_s"].to_numpy()[:-1]])
    markers = report["marker"].tolist()
    return lambda: plot_gaps(np.arange(len(filled)) / rate, np.zeros_like(filled), filled,
                             markers, sentence_bounds=starts)


def _figures(study: Path):
    """(name, dataset, build) for every figure: build() returns a matplotlib Figure."""
    import pandas as pd

    from facemotion.ingest.displacement_file import load_displacements
    from facemotion.ingest.displacements import split_roles
    from facemotion.plots.comparison import plot_paper_comparison
    from facemotion.plots.error_curves import plot_error_curves
    from facemotion.plots.rank import plot_r_values
    from facemotion.plots.regions import plot_orthogonal_directions, plot_region_maps
    from facemotion.plots.selection import plot_selection_agreement
    from facemotion.plots.sweep import plot_sentence_sweep
    from facemotion.ranking.result import selection_table
    from facemotion.ranking.routes import rank_for_study
    from facemotion.regions.prediction import fit_coefficients

    # the default study's order (S1, S2a, S2b, then the starred ones)
    datasets = sorted((p.parent.parent.name for p in study.glob("*/data/displacements.npz")),
                      key=lambda s: (s.endswith("_star"), s))
    labels = {"S2a_star": "S2a*", "S2b_star": "S2b*"}
    out = []
    curves, r_tables = {}, {}
    for ds in datasets:
        lab = labels.get(ds, ds)
        d = load_displacements(study / ds / "data" / "displacements.npz")
        train, held = split_roles(d, study / ds / "data" / "sentences.tsv")
        ranking = rank_for_study(train.A, train.labels)
        X = fit_coefficients(ranking, 10)
        out.append(("regions", ds, lambda d=d, X=X: plot_region_maps(d.neutral, d.labels, X)))
        out.append(("orthogonal", ds, lambda d=d, r=ranking: plot_orthogonal_directions(
            d.neutral, d.labels, r.R, r.labels_in_order, n_pivots=4)))
        curve = pd.read_csv(study / ds / "eval" / "error_curve.tsv", sep="\t")
        curves[lab] = curve
        n_held = len(held.labels)
        out.append(("error_curve", ds, lambda c=curve, lab=lab, n=n_held:
                    plot_error_curves({lab: c}, n_markers={lab: n})))
        out.append(("trajectory", ds, _trajectory_figure(study, ds, held, ranking)))
        r_table = pd.read_csv(study / ds / "qr" / "r_values.tsv", sep="\t",
                              dtype={"marker": str})
        r_tables[lab] = r_table
        out.append(("r_values", ds, lambda r=r_table, lab=lab: plot_r_values(
            {lab: r}, tolerances=(0.25, 0.5, 1.0))))
        sweep = pd.read_csv(study / ds / "qr" / "sentence_sweep.tsv", sep="\t",
                            dtype={"marker": str})
        out.append(("sentence_sweep", ds, lambda s=sweep: plot_sentence_sweep(s)))
        out.append(("gaps", ds, _gaps_figure(study, ds, d.rate)))
    out.append(("error_curves_all", "all", lambda: plot_error_curves(curves)))
    out.append(("r_values_all", "all", lambda: plot_r_values(r_tables,
                                                              tolerances=(0.25, 0.5, 1.0))))
    sel = selection_table({lab: t["marker"] for lab, t in r_tables.items()}, 10)
    out.append(("selected_markers", "all", lambda: plot_selection_agreement(sel, k=10)))
    comp = study / "tables" / "paper_comparison.tsv"
    if comp.exists():
        table = pd.read_csv(comp, sep="\t", keep_default_na=False)
        out.append(("paper_comparison", "all", lambda: plot_paper_comparison(table)))
    return out


def run_once(study: Path, only: set[str] | None, out_dir: Path | None,
             rounds: int) -> dict[str, float]:
    """CPU ms per figure type (summed over datasets) in this process: each figure's least
    time over ``rounds`` passes (the machine's other load only ever adds time)."""
    import matplotlib

    matplotlib.use("Agg")
    from facemotion.plots.save import figure_bytes

    figures = [f for f in _figures(study) if only is None or f[0] in only]
    # warm-up: fonts, caches, lazy imports (every job pays them once; not per figure)
    figure_bytes(figures[0][2](), "png")
    best: dict[tuple[str, str], float] = {}
    for r in range(rounds):
        for name, ds, build in figures:
            t = time.process_time()
            fig = build()
            png = figure_bytes(fig, "png")
            ms = 1000 * (time.process_time() - t)
            best[name, ds] = min(ms, best.get((name, ds), ms))
            if out_dir is not None and r == 0:
                out_dir.mkdir(parents=True, exist_ok=True)
                (out_dir / f"{name}_{ds}.png").write_bytes(png)
    out: dict[str, float] = {}
    for (name, _), ms in best.items():
        out[name] = out.get(name, 0.0) + ms
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("study", type=Path)
    ap.add_argument("--repeats", type=int, default=3, help="processes per version")
    ap.add_argument("--rounds", type=int, default=2, help="passes over the figures a process")
    ap.add_argument("--baseline", type=Path, help="src directory of the version to compare")
    ap.add_argument("--only", help="comma-separated figure names")
    ap.add_argument("--out", type=Path, help="write this code's PNGs here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    only = set(args.only.split(",")) if args.only else None
    if args.child:
        print(json.dumps(run_once(args.study, only, args.out, args.rounds)))
        return
    versions = {"this": ROOT / "src"}
    if args.baseline:
        versions["baseline"] = args.baseline.resolve()
    runs: dict[str, list[dict[str, float]]] = {v: [] for v in versions}
    for i in range(args.repeats):
        for v, src in versions.items():
            env = {**os.environ, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1",
                   "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
            cmd = [sys.executable, __file__, str(args.study), "--child",
                   "--rounds", str(args.rounds)]
            if args.only:
                cmd += ["--only", args.only]
            if args.out and v == "this" and i == 0:
                cmd += ["--out", str(args.out)]
            res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            runs[v].append(json.loads(res.stdout.strip().splitlines()[-1]))
    names = list(runs["this"][0])
    what = f"figure (CPU ms, least of {args.repeats}x{args.rounds})"
    head = f"{what:34s}" + "".join(
        f"{v:>10s}" for v in versions)
    print(head + ("     ratio" if args.baseline else ""))
    total = dict.fromkeys(versions, 0.0)
    for n in names:
        med = {v: min(r[n] for r in runs[v]) for v in versions}
        for v in versions:
            total[v] += med[v]
        line = f"{n:34s}" + "".join(f"{med[v]:10.0f}" for v in versions)
        if args.baseline:
            line += f"{med['this'] / med['baseline']:10.2f}"
        print(line)
    line = f"{'total':34s}" + "".join(f"{total[v]:10.0f}" for v in versions)
    if args.baseline:
        line += f"{total['this'] / total['baseline']:10.2f}"
    print(line)


if __name__ == "__main__":
    main()
