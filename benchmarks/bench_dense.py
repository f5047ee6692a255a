"""Dense faces at scale: the ranking at the machine's GEMM rate, loading with long gaps, A on
disk within a memory bound, and dense faces of thousands of points, with baselines measured
in the same run.

    python benchmarks/bench_dense.py [--threads 2] [--reps 5] [--quick] [--only NAME ...]
                                     [--fill-baseline] [--scipy-dense]

Every number comes from this run: BLAS threads fixed at ``--threads`` for our routes AND for
scipy (threadpoolctl), repetitions interleaved (ours, baseline, ours, ...), medians reported,
the machine's double-precision GEMM rate measured at the same thread count at the start and the
end (the peak is the larger). Peak RSS is measured per case in a child process (its VmHWM).
Writes benchmarks/out/bench_dense.tsv (one row per measurement) and prints it.

Cases (``--only``):

``peak``      GEMM rate, 1 and ``--threads`` threads.
``rank10x``   57 markers at 10x the paper's frames (~600,000 rows): our ranking (Gram route)
              vs scipy's pivoted QR, same threads; the A^T A pass's rate and fraction of the
              GEMM peak for both Gram routes ("rows", "blas") and numpy's ``A.T @ A``.
              Target: >= 20x.
``load20k``   a 468-landmark, 20,000-frame TRC with three long gaps (written once): read +
              head alignment + gap filling + A, end to end (wall, CPU-s, peak RSS), against
              pandas' C parser reading the same file's numbers in the same run (children
              interleaved); with ``--fill-baseline`` (always in ``--quick``) also the gap
              filling alone against the previous method (one thin SVD of the whole take with
              every marker as donor; minutes at full size). Target: <= 15 s.
``reader``    TRC parse rate (MB/s) and peak RSS / file size, fast path vs the exact
              line-by-line path (the exact reader's method) on the same file.
``mem4g``     a 4 GB A written block by block, then ranked from disk in a child process:
              peak RSS. Target: < 1 GiB.
``dense``     468 x 108,000 frames and 5,023 x 25,000 frames (``--quick``: 1/8 of the
              frames), A on disk -> r_values and the held-out error curve at k_max = 100;
              wall time, peak RSS, the ratio to scipy's pivoted QR where it fits
              (``--scipy-dense`` also for 5,023 points: slow), and a fit of time against frames
              and points (log-log slope).
``talker``    the dense virtual talker D5023 (40 sentences; ``--quick``: 8) loaded by the study's
              path: the randomized route's residual ||A - A_S X||_F over deterministic pivoted
              QR's at k = 10, 50, 100 (target: <= 1.05), and both routes' times.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "out"
sys.path.insert(0, str(HERE))

ROWS: list[dict] = []


def row(case, measure, value, unit, note="", target=None, met=None):
    ROWS.append({"case": case, "measure": measure, "value": value, "unit": unit,
                 "target": "" if target is None else target,
                 "met": "" if met is None else ("yes" if met else "NO"), "note": note})
    verdict = "" if met is None else ("yes" if met else "NO")
    print(f"{case:9s} {measure:42s} {value:12.4g} {unit:8s} "
          f"{'' if target is None else target!s:>8s} {verdict:4s} {note}", flush=True)


def vm_hwm_mib() -> float:
    """This process's peak resident set (VmHWM, MiB). Not ru_maxrss: Linux carries a forked
    child's maxrss over from its parent across exec, so a child of a big parent reads big."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def child(args: list[str]) -> tuple[dict, float]:
    """Run this file with ``--worker ...`` in a child; returns (its JSON, its peak RSS MiB)."""
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", *args],
                       stdout=subprocess.PIPE, env=os.environ.copy())
    if p.returncode != 0:
        raise RuntimeError(f"worker {args} failed ({p.returncode})")
    res = json.loads(p.stdout.decode().strip().splitlines()[-1])
    return res, res.pop("peak_rss_mib")


# ------------------------------------------------------------------------------------ cases

def case_peak(threads):
    from facemotion.ranking.gram import gemm_rate

    p1 = gemm_rate(1)
    pt = gemm_rate(threads)
    row("peak", "gemm_rate_1_thread", p1, "GFLOP/s", "dgemm 2000x2000, best of 3")
    row("peak", f"gemm_rate_{threads}_threads", pt, "GFLOP/s", "dgemm 2000x2000, best of 3")
    return pt


def case_rank10x(threads, reps, peak):
    import scipy.linalg
    from bench_qr import median_times, synthetic
    from threadpoolctl import threadpool_limits

    from facemotion.ranking.gram import gram, gram_flops
    from facemotion.ranking.routes import rank_markers

    A, labels, _ = synthetic(2000, seed=1)
    rows, n = A.shape
    with threadpool_limits(threads, user_api="blas"):
        (t_ours, t_scipy), (rk, (_, P)) = median_times(
            [lambda: rank_markers(A, labels, method="gram", threads=threads),
             lambda: scipy.linalg.qr(A, mode="r", pivoting=True, check_finite=False)], reps)
        assert np.array_equal(rk.order, P), "pivots differ from scipy's pivoted QR"
        (t_rows, t_blas, t_np), _ = median_times(
            [lambda: gram(A, threads=threads, route="rows"),
             lambda: gram(A, threads=threads, route="blas"),
             lambda: A.T @ A], reps)
    ratio = t_scipy / t_ours
    note = f"{rows}x{n}, {threads} BLAS threads both, median of {reps} interleaved"
    row("rank10x", "scipy_pivoted_qr_s", t_scipy, "s", note)
    row("rank10x", "ours_gram_route_s", t_ours, "s", "same pivots as scipy (asserted)")
    row("rank10x", "speedup_vs_scipy", ratio, "x", note, ">=20", ratio >= 20)
    fl = gram_flops(rows, n)
    for name, t in (("rows", t_rows), ("blas", t_blas), ("numpy_AtA", t_np)):
        row("rank10x", f"AtA_pass_{name}_GFLOPs", fl / t / 1e9, "GFLOP/s",
            f"{t * 1e3:.1f} ms; syrk flops rows*n*(n+1)")
        row("rank10x", f"AtA_pass_{name}_fraction_of_peak", fl / t / 1e9 / peak, "",
            f"peak {peak:.1f} GFLOP/s at {threads} threads")


def _dense_trc(frames, gaps_s, path: Path):
    from dense_face import dense_recording

    from facemotion.io.trc import write_trc

    if not path.exists():
        truth, gapped = dense_recording(frames, gaps_s=gaps_s, rate=30.0, seed=0)
        write_trc(path, gapped)
    return path


def case_load20k(threads, reps, quick, fill_baseline):
    frames = 4000 if quick else 20000
    data = OUT / "data"
    data.mkdir(parents=True, exist_ok=True)
    trc = _dense_trc(frames, (2.0, 3.0, 5.0), data / f"dense_468x{frames}_3gaps.trc")
    mb = trc.stat().st_size / 2**20
    walls, cpus, rss, pwalls, prss = [], [], [], [], []
    for _ in range(max(1, reps // 2)):  # interleaved children: ours, pandas, ours, ...
        res, peak = child(["load", str(trc), str(threads)])
        walls.append(res["wall_s"])
        cpus.append(res["cpu_s"])
        rss.append(peak)
        parts = res
        pres, ppeak = child(["pandas", str(trc)])
        pwalls.append(pres["wall_s"])
        prss.append(ppeak)
    wall, pwall = float(np.median(walls)), float(np.median(pwalls))
    note = f"468 x {frames} frames, 3 long gaps (2, 3, 5 s), TRC {mb:.0f} MB; median of " \
        f"{len(walls)}, {threads} BLAS threads"
    row("load20k", "load_dataset_end_to_end_s", wall, "s", note,
        "<=15" if not quick else None, wall <= 15 if not quick else None)
    row("load20k", "load_dataset_cpu_s", float(np.median(cpus)), "CPU-s",
        "user+system of the loading process, all threads")
    for k in ("read_s", "fill_s"):
        row("load20k", k, parts[k], "s", "inside the end-to-end run")
    row("load20k", "peak_rss_MiB", float(np.median(rss)), "MiB", f"file {mb:.0f} MB")
    row("load20k", "peak_rss_over_file", float(np.median(rss)) * 2**20 / trc.stat().st_size,
        "x", "the whole recording is held while loading")
    row("load20k", "pandas_read_csv_s", pwall, "s",
        "baseline: pandas' C parser reads the same TRC's numbers (no validation, no A)")
    row("load20k", "pandas_peak_rss_MiB", float(np.median(prss)), "MiB", "baseline")
    row("load20k", "end_to_end_over_pandas_read", wall / pwall, "x",
        "whole loading path / parsing alone by pandas")
    row("load20k", "read_over_pandas_read", parts["read_s"] / pwall, "x",
        "our TRC reader / pandas")
    if not fill_baseline:
        return
    res, _ = child(["fillcmp", str(trc), str(threads)])
    row("load20k", "fill_gaps_previous_svd_s", res["old_s"], "s",
        "thin SVD of the whole take, every marker a donor (previous method)")
    row("load20k", "fill_gaps_now_s", res["new_s"], "s", "30 donors, 10 s window, eigh")
    row("load20k", "fill_speedup", res["old_s"] / res["new_s"], "x")
    row("load20k", "fill_rms_error_previous_mm", res["old_err"], "mm", "vs removed truth")
    row("load20k", "fill_rms_error_now_mm", res["new_err"], "mm", "vs removed truth")


def case_reader(threads, reps, quick):
    frames = 4000 if quick else 20000
    trc = _dense_trc(frames, (2.0, 3.0, 5.0), OUT / "data" / f"dense_468x{frames}_3gaps.trc")
    mb = trc.stat().st_size / 2**20
    fast, exact = [], []
    for _ in range(max(1, reps // 2)):  # interleaved children
        r1, p1 = child(["read", str(trc), "fast"])
        r2, p2 = child(["read", str(trc), "exact"])
        fast.append((r1["wall_s"], p1, r1["baseline_mib"]))
        exact.append((r2["wall_s"], p2, r2["baseline_mib"]))
    for name, res in (("fast", fast), ("exact_line_by_line", exact)):
        t = float(np.median([r[0] for r in res]))
        peak = float(np.median([r[1] - r[2] for r in res]))
        row("reader", f"trc_{name}_MBps", mb / t, "MB/s", f"{mb:.0f} MB, median of {len(res)}")
        row("reader", f"trc_{name}_rss_over_file", peak * 2**20 / trc.stat().st_size, "x",
            "peak RSS above the interpreter's, / file size")
    row("reader", "fast_speedup", float(np.median([e[0] for e in exact])
                                        / np.median([f[0] for f in fast])), "x")


def case_mem4g(threads, quick):
    gb = 0.5 if quick else 4.0
    n = 468
    rows = int(gb * 1e9 / 8 / n) // 3 * 3
    with tempfile.TemporaryDirectory(dir=OUT) as tmp:
        path = Path(tmp) / "A.npz"
        t0 = time.perf_counter()
        res, peak_w = child(["write", str(path), str(rows), str(n)])
        row("mem4g", "write_A_s", time.perf_counter() - t0, "s",
            f"{rows}x{n} ({path.stat().st_size / 1e9:.2f} GB), streamed")
        row("mem4g", "write_peak_rss_MiB", peak_w, "MiB")
        res, peak = child(["rank", str(path), str(threads), "0"])
        row("mem4g", "rank_from_disk_s", res["wall_s"], "s", f"gram route, {threads} threads")
        row("mem4g", "rank_from_disk_peak_rss_MiB", peak, "MiB",
            f"A = {path.stat().st_size / 2**30:.2f} GiB on disk",
            "<1024" if not quick else None, peak < 1024 if not quick else None)


def case_dense(threads, reps, quick, scipy_dense):
    scale = 8 if quick else 1
    cases = [(468, 108000 // scale), (5023, 25000 // scale)]
    fit_frames = [(468, 108000 // scale // 4), (468, 108000 // scale // 2)]
    fit_points = [(1833, 25000 // scale)]
    timings = {}
    with tempfile.TemporaryDirectory(dir=OUT) as tmp:
        for n, frames in cases + fit_frames + fit_points:
            path = Path(tmp) / f"A_{n}x{frames}.npz"
            child(["write", str(path), str(3 * frames), str(n), "dense"])
            res, peak = child(["rank", str(path), str(threads), "100"])
            timings[(n, frames)] = res["wall_s"]
            if (n, frames) in cases:
                note = f"A {3 * frames}x{n} on disk ({path.stat().st_size / 2**30:.2f} GiB)"
                row("dense", f"n{n}_F{frames}_to_r_values_and_curve_s", res["wall_s"], "s",
                    note + f"; route {res['method']}, k_max 100")
                row("dense", f"n{n}_F{frames}_peak_rss_MiB", peak, "MiB")
                row("dense", f"n{n}_F{frames}_AtA_fraction_of_peak", res.get("gram_frac", np.nan),
                    "", f"A^T A pass {res.get('gram_gflops', np.nan):.1f} GFLOP/s")
                if n < 2000 or scipy_dense:
                    r2, p2 = child(["scipy", str(path), str(threads)])
                    row("dense", f"n{n}_F{frames}_scipy_pivoted_qr_s", r2["wall_s"], "s",
                        f"peak RSS {p2:.0f} MiB")
                    row("dense", f"n{n}_F{frames}_ratio_scipy_over_ours", r2["wall_s"]
                        / res["qr_s"], "x", "ranking only (same A in memory for scipy)")
                    if "P" in r2 and "order" in res:
                        row("dense", f"n{n}_F{frames}_same_first_100_pivots",
                            float(r2["P"][:100] == res["order"][:100]), "bool")
    f468 = sorted((f, t) for (n, f), t in timings.items() if n == 468)
    if len(f468) >= 2:
        slope = np.polyfit(np.log([f for f, _ in f468]), np.log([t for _, t in f468]), 1)[0]
        row("dense", "time_vs_frames_loglog_slope_468", slope, "",
            ", ".join(f"{f}: {t:.1f} s" for f, t in f468))
    F = 25000 // scale
    pts = sorted((n, t) for (n, f), t in timings.items() if f == F)
    if len(pts) >= 2:
        slope = np.polyfit(np.log([n for n, _ in pts]), np.log([t for _, t in pts]), 1)[0]
        row("dense", f"time_vs_points_loglog_slope_F{F}", slope, "",
            ", ".join(f"{n}: {t:.1f} s" for n, t in pts))


def case_talker(threads, quick):
    """The randomized route on the dense virtual talker (target: within 1.05x of pivoted QR's
    residual at k = 10, 50 and 100), in a child: D5023, its sentences loaded by the
    study's path, training sentences ranked by both routes."""
    n_sent = 8 if quick else 40
    res, peak = child(["talker", str(threads), str(n_sent)])
    note = (f"D5023, {n_sent} sentences, A {res['rows']}x{res['n']} (training), "
            f"{threads} threads")
    row("talker", "simulate_and_load_s", res["load_s"], "s", note)
    row("talker", "gram_route_all_pivots_s", res["gram_s"], "s", "deterministic pivoted QR")
    row("talker", "randomized_route_k100_s", res["rand_s"], "s", "first 100 pivots")
    for k, r in zip(res["k"], res["ratio"], strict=True):
        row("talker", f"residual_ratio_randomized_over_qr_k{k}", r, "x",
            "||A - A_S X||_F, same k", "<=1.05", r <= 1.05)
    row("talker", "peak_rss_MiB", peak, "MiB")


# ------------------------------------------------------------------------------------ workers

def _worker_load(argv):
    import logging

    from facemotion.ingest import gaps, loading
    from facemotion.io import registry as readers
    trc, threads = argv[1], int(argv[2])
    os.environ["OPENBLAS_NUM_THREADS"] = str(threads)
    spent = {"read_s": 0.0, "fill_s": 0.0}

    def timed(fn, key):
        def inner(*a, **k):
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[key] += time.perf_counter() - t0
        return inner
    readers.read_recording = timed(readers.read_recording, "read_s")
    gaps.fill_gaps = timed(gaps.fill_gaps, "fill_s")  # load_dataset imports them at call
    logging.disable(logging.INFO)
    t0, c0 = time.perf_counter(), time.process_time()
    ds = loading.load_dataset([trc], "trc", train=[0], heldout=[])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    assert np.isfinite(ds.displacements.A).all()
    return {"wall_s": wall, "cpu_s": cpu, **spent}


def _worker_pandas(argv):
    import pandas as pd
    trc = argv[1]
    t0 = time.perf_counter()
    df = pd.read_csv(trc, sep="\t", skiprows=5, header=None, engine="c")
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "frames": len(df)}


def _worker_fillcmp(argv):
    from dense_face import dense_recording
    from svd_fill_baseline import fill_gaps_svd

    from facemotion.ingest.gaps import fill_gaps
    from facemotion.io.trc import read_trc
    trc = argv[1]
    rec = read_trc(trc)
    frames = rec.n_frames
    truth, _ = dense_recording(frames, gaps_s=(2.0, 3.0, 5.0), rate=30.0, seed=0)
    miss = ~np.isfinite(rec.points).all(axis=2)
    t0 = time.perf_counter()
    new, _ = fill_gaps(rec)
    t_new = time.perf_counter() - t0
    t0 = time.perf_counter()
    old = fill_gaps_svd(rec)
    t_old = time.perf_counter() - t0

    def err(x):  # truth is from the generator, the file has 6 decimals: ~1e-6 mm
        return float(np.sqrt(np.mean((x.points - truth.points)[miss] ** 2)))
    return {"new_s": t_new, "old_s": t_old, "new_err": err(new), "old_err": err(old)}


def _worker_read(argv):
    from facemotion.io import base as io_base
    from facemotion.io.trc import read_trc
    trc, mode = argv[1], argv[2]
    base = vm_hwm_mib()
    if mode == "exact":
        io_base.FAST_TEXT = False
    t0 = time.perf_counter()
    rec = read_trc(trc)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "baseline_mib": base, "frames": rec.n_frames}


def _worker_write(argv):
    from facemotion.ingest.displacement_file import DisplacementsWriter
    path, rows, n = argv[1], int(argv[2]), int(argv[3])
    dense = len(argv) > 4
    return write_synthetic_A(DisplacementsWriter, path, rows, n, dense)


def _worker_rank(argv):
    from facemotion.ingest.displacement_file import open_displacements
    from facemotion.ranking.gram import gemm_rate, gram, gram_flops
    from facemotion.ranking.routes import rank_markers
    from facemotion.regions.prediction import error_curve
    path, threads, k_max = argv[1], int(argv[2]), int(argv[3]) or None
    t0 = time.perf_counter()
    f = open_displacements(path)
    S = len(f.sentences)
    train = f.rows(list(range(max(1, S - max(1, S // 10)))))
    held = f.rows(list(range(max(1, S - max(1, S // 10)), S)))
    t1 = time.perf_counter()
    rk = rank_markers(train, method="auto", k_max=k_max, threads=threads)
    t_qr = time.perf_counter() - t1
    out = {"method": rk.method, "qr_s": t_qr, "order": rk.order[:100].tolist()}
    if k_max:
        B = held.read()
        error_curve(rk, B, f.labels, k_max=k_max)
    out["wall_s"] = time.perf_counter() - t0
    if k_max and f.shape[1] < 2000:  # the Gram pass alone, and the peak, same process
        t2 = time.perf_counter()
        gram(train, threads=threads)
        tg = time.perf_counter() - t2
        gf = gram_flops(*train.shape) / tg / 1e9
        out.update(gram_gflops=gf, gram_frac=gf / gemm_rate(threads))
    return out


def _worker_talker(argv):
    import logging

    from facemotion.ingest.loading import load_dataset
    from facemotion.ranking.routes import rank_markers, route_accuracy
    from facemotion.virtual.dense import simulate_dense, write_dense_subject
    from facemotion.virtual.talker import HEAD_LABELS
    threads, n_sent = int(argv[1]), int(argv[2])
    logging.disable(logging.INFO)
    t0 = time.perf_counter()
    subj = simulate_dense("D5023", seed=1, n_sentences=n_sent,
                          shared_data=os.environ.get("FACEMOTION_SHARED_DATA"))
    n_train = n_sent - max(1, n_sent // 4)
    with tempfile.TemporaryDirectory(dir=OUT) as tmp:
        paths = write_dense_subject(subj, tmp, "D", "trc")
        ds = load_dataset([str(p) for p in paths], "trc", head_markers=list(HEAD_LABELS),
                          exclude_markers=list(HEAD_LABELS), train=list(range(n_train)),
                          heldout=list(range(n_train, n_sent))).displacements
    A = ds.A[ds.row_sentence < n_train]
    load_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    rk = rank_markers(A, ds.labels, method="auto", k_max=100, threads=threads)
    rand_s = time.perf_counter() - t1
    t1 = time.perf_counter()
    rank_markers(A, ds.labels, method="gram", threads=threads)
    gram_s = time.perf_counter() - t1
    acc = route_accuracy(A, rk, threads=threads)
    return {"rows": A.shape[0], "n": A.shape[1], "load_s": load_s, "rand_s": rand_s,
            "gram_s": gram_s, "method": rk.method, **acc}


def _worker_scipy(argv):
    import scipy.linalg
    from threadpoolctl import threadpool_limits

    from facemotion.ingest.displacement_file import open_displacements
    path, threads = argv[1], int(argv[2])
    f = open_displacements(path)
    S = len(f.sentences)
    A = f.rows(list(range(max(1, S - max(1, S // 10))))).read()
    with threadpool_limits(threads, user_api="blas"):
        t0 = time.perf_counter()
        _, P = scipy.linalg.qr(A, mode="r", pivoting=True, check_finite=False)
        wall = time.perf_counter() - t0
    return {"wall_s": wall, "P": P[:100].tolist()}


WORKERS = {name: globals()[f"_worker_{name}"] for name in
           ("load", "pandas", "fillcmp", "read", "write", "rank", "talker", "scipy")}


def worker(argv):
    """Run one case in this (fresh) process: ``argv`` is the case's name and arguments."""
    if argv[0] not in WORKERS:
        raise SystemExit(f"unknown worker {argv[0]}")
    return WORKERS[argv[0]](argv)


def write_synthetic_A(Writer, path, rows, n, dense):
    """A (rows x n) of smooth low-rank motion plus 0.05 mm noise, written in blocks; 10
    sentences."""
    rng = np.random.default_rng(0)
    k = 40
    W = rng.standard_normal((k, n)) * np.exp(-np.arange(k) / 8.0)[:, None]
    w = Writer(path, [f"V{j:04d}" for j in range(n)], rows)
    step = 3 * max(1, (32 * 2**20) // (8 * n * 3))
    freqs = rng.uniform(0.2, 3.0, k)
    for a in range(0, rows, step):
        m = min(step, rows - a)
        t = (a + np.arange(m)) / 90.0
        blk = np.sin(np.outer(t, freqs)) @ W
        blk += 0.05 * np.random.default_rng([1, a]).standard_normal(blk.shape)
        w.write_rows(blk)
    S = 10
    F = rows // 3
    sent = np.minimum(np.arange(F) * S // F, S - 1)
    w.close(sentences=np.array([f"s{i}" for i in range(S)]),
            row_sentence=np.repeat(sent, 3), row_frame=np.repeat(np.arange(F), 3),
            rate=np.array(30.0), fill_mask=np.zeros((F, n), dtype=bool),
            head_residual=np.zeros(F), neutral=np.zeros((n, 3)))
    return {"rows": rows, "n": n}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        res = worker(argv[1:])
        res["peak_rss_mib"] = vm_hwm_mib()
        print(json.dumps(res))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--scipy-dense", action="store_true")
    ap.add_argument("--fill-baseline", action="store_true",
                    help="load20k: also the previous gap filling (minutes at full size)")
    ap.add_argument("--only", nargs="*", default=["peak", "rank10x", "load20k", "reader",
                                                  "mem4g", "dense", "talker"])
    ap.add_argument("--page", help="replace the table between the bench-dense markers there "
                    "(docs/performance.md) with this run's rows")
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()[0]
    print(f"threads {args.threads}, reps {args.reps}, load average at start {load:.2f} "
          f"on {os.cpu_count()} CPUs" + (" (BUSY: numbers are provisional)"
                                          if load > 0.5 * (os.cpu_count() or 1) else ""))
    from facemotion.ranking.gram import gemm_rate

    peak = case_peak(args.threads) if "peak" in args.only else gemm_rate(args.threads)
    if "rank10x" in args.only:
        case_rank10x(args.threads, args.reps, peak)
    if "load20k" in args.only:
        case_load20k(args.threads, args.reps, args.quick,
                     args.fill_baseline or args.quick)
    if "reader" in args.only:
        case_reader(args.threads, args.reps, args.quick)
    if "mem4g" in args.only:
        case_mem4g(args.threads, args.quick)
    if "dense" in args.only:
        case_dense(args.threads, args.reps, args.quick, args.scipy_dense)
    if "talker" in args.only:
        case_talker(args.threads, args.quick)
    peak_end = gemm_rate(args.threads)
    row("peak", "gemm_rate_at_end", peak_end, "GFLOP/s", "same thread count, after the cases")
    load_end = os.getloadavg()[0]
    row("machine", "load_average_start_end", load_end, "", f"start {load:.2f}")
    tmp = OUT / "bench_dense.tsv.tmp"
    cols = ["case", "measure", "value", "unit", "target", "met", "note"]
    with open(tmp, "w") as fh:
        fh.write("\t".join(cols) + "\n")
        for r in ROWS:
            fh.write("\t".join(f"{r[c]:.6g}" if isinstance(r[c], float) else str(r[c])
                               for c in cols) + "\n")
    tmp.replace(OUT / "bench_dense.tsv")
    if args.page:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from rule_times import update_page

        update_page(args.page, page_table(args, load, load_end), "bench-dense")
    return 0


def page_table(args, load_start: float, load_end: float) -> str:
    """This run's rows as docs/performance.md's table (nothing the run did not measure)."""
    lines = [f"Written by `python benchmarks/bench_dense.py --only {' '.join(args.only)} "
             f"--page docs/performance.md` (part of `make bench`) on {time.strftime('%Y-%m-%d')}"
             f": {args.threads} BLAS threads, medians of {args.reps} interleaved repetitions"
             f"{', --quick sizes' if args.quick else ''}; load average {load_start:.2f} at the "
             f"start and {load_end:.2f} at the end.", "",
             "| case | measure | value | unit | target | met | note |",
             "|---|---|---:|---|---|---|---|"]
    for r in ROWS:
        v = r["value"]
        v = f"{v:.4g}" if isinstance(v, float) else str(v)
        lines.append(f"| {r['case']} | {r['measure']} | {v} | {r['unit']} | {r['target']} | "
                     f"{r['met']} | {r['note']} |")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
