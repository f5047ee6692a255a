"""Streamed loading at the sizes of hours of dense faces: file -> Gram -> r values -> error
curve in bounded memory, beside pandas.read_csv (TRC) or ezc3d (C3D) reading the same file in
the same run.

    python benchmarks/bench_stream.py [--cases trc468 trc5023 ...] [--max-gib 1.0]
                                      [--k-max 100] [--threads 2] [--fit] [--arrow]
                                      [--page docs/performance.md]

Each measurement runs in its own child process; its peak RSS is the child's high-water mark
(VmHWM). Ours: :func:`facemotion.ingest.streaming.stream_dataset` on the take (every check,
gap filling, displacements to a file, the Gram of the rows; the TRC text is read and parsed a
block ahead in a thread of its own, :mod:`facemotion.io.trc_blocks`, the rest on one core),
then :func:`facemotion.ranking.qr.rank_from_gram` (the r values), then the error curve for
k = 1 .. ``--k-max`` (default 100) by
:func:`facemotion.regions.streamed_curve.streamed_error_curve` on ``--threads`` threads
(default 2, the machine's cores) over the take's last tenth of frames (``HELDOUT_SHARE``),
read in blocks from the displacements file the load wrote (A is never in memory whole).

That is the workload of the baseline the targets were set against: the whole-take path at
468 x 108,000 frames took 47.6 s for file -> r values -> the error curve of the last of 10
sentences at k_max = 100 (bench_dense.py's dense case after loading), 5.3x pandas. A single
take cannot be split into training and held-out sentences by the streamed loader, so the
curve's frames are also in the Gram: its errors are in-sample, but its cost is exactly that
of a held-out curve of as many frames (the curve's arithmetic does not depend on where the
rows come from). The dense study's own setting, ``qr.k_max: 40`` in config/dense.yaml, costs
less (``--k-max 40``); ``--k-max 0`` times file -> r values only. The load's time and the
curve's are also reported on rows of their own.

Baselines of the same file, interleaved with ours (ours, baseline): ``pandas.read_csv`` (C
parser, the whole file into one frame) for TRC; ``ezc3d.c3d`` for C3D; with ``--arrow``
(pyarrow installed) also pyarrow's ``read_csv`` (multithreaded) and its streaming
``open_csv`` (one thread, batches), which is how the block parser was chosen.

Cases (``--cases``; the files are written once into benchmarks/out/stream/):

``trc468``   468 points x 108,000 frames (an hour at 30 fps), about 1.5 GB. Targets: peak RSS
             <= 1 GiB at the default bound, time <= 2x pandas.read_csv.
``trc5023``  5,023 points x 25,000 frames, about 3.8 GB. Targets: <= 1.5 GiB, <= 2x pandas.
``trc10g``   5,023 points x 65,000 frames (about 10 GB): run alone (``--cases trc10g``),
             never in the tests or CI; pandas' baseline alone needs about 13 GiB, so it is
             left out unless ``--huge-baseline``.
``c3d65k``   468 points x 65,535 frames (the C3D frame limit) as C3D.

``--fit`` adds the time and memory exponents: ours on 468 points at 1/8, 1/4 and 1/2 of
108,000 frames and on 117, 234 and 468 points at 13,500 frames, log-log slopes by least
squares.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "out" / "stream"
sys.path.insert(0, str(HERE))

CASES = {"trc468": ("trc", 468, 108_000), "trc5023": ("trc", 5023, 25_000),
         "trc10g": ("trc", 5023, 65_000), "c3d65k": ("c3d", 468, 65_535)}
#: The curve's share of the take (its last frames) and its largest k: the baseline's (the
#: issue's 47.6 s at 468 x 108,000 frames: bench_dense.py's dense case, the last of 10
#: sentences held out, k_max = 100).
HELDOUT_SHARE = 0.1
K_MAX = 100
#: Threads of the error curve (``--threads``): the machine's two cores, as bench_dense.py's
#: ``--threads 2`` that timed the baseline.
THREADS = 2
TARGETS = {"trc468": (1024.0, 2.0), "trc5023": (1536.0, 2.0), "trc10g": (1536.0, None)}
ROWS: list[dict] = []


def row(case, measure, value, unit, note="", target=None, met=None):
    ROWS.append({"case": case, "measure": measure, "value": value, "unit": unit,
                 "target": "" if target is None else target,
                 "met": "" if met is None else ("yes" if met else "NO"), "note": note})
    print(f"{case:8s} {measure:34s} {value:12.4g} {unit:5s} {target or '':>8} "
          f"{'' if met is None else ('yes' if met else 'NO'):4s} {note}", flush=True)


def vertices(n: int) -> np.ndarray:
    """n face points: the canonical mesh's vertices (mm), subdivided when n > 468."""
    from dense_face import MESH

    from facemotion.virtual.dense import read_canonical_mesh, subdivide_longest_edges

    v, tri = read_canonical_mesh(MESH)
    v = 10.0 * np.asarray(v, dtype=float)
    if n > len(v):
        v = subdivide_longest_edges(v, tri, n)[0]
    return np.asarray(v[:n], dtype=float)


def write_take(path: Path, fmt: str, n: int, frames: int, rate: float = 30.0) -> Path:
    """The dense benchmark face (the motion of benchmarks/dense_face.py) written block by
    block, so that no file needs its recording in memory."""
    if path.exists():
        return path
    v = vertices(n)
    labels = [f"V{j:04d}" for j in range(n)]
    tmp = path.with_name(path.name + ".tmp")
    if fmt == "c3d":
        from facemotion.io.c3d import write_c3d
        from facemotion.io.recording import Recording

        write_c3d(tmp, Recording(labels, _block(v, 0, frames, rate), rate))
        return tmp.replace(path)
    step = max(1, 4_000_000 // (3 * n))
    with open(tmp, "w") as fh:
        fh.write(f"PathFileType\t4\t(X/Y/Z)\t{path.name}\n"
                 "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
                 "OrigDataStartFrame\tOrigNumFrames\n"
                 f"{rate:g}\t{rate:g}\t{frames}\t{n}\tmm\t{rate:g}\t1\t{frames}\n"
                 "Frame#\tTime\t" + "\t".join(f"{lab}\t\t" for lab in labels) + "\n"
                 "\t\t" + "\t".join(f"X{j}\tY{j}\tZ{j}" for j in range(1, n + 1)) + "\n\n")
        for a in range(0, frames, step):
            b = min(frames, a + step)
            pts = _block(v, a, b, rate)
            lead = np.stack([np.arange(a + 1, b + 1), np.arange(a, b) / rate], axis=1)
            np.savetxt(fh, np.concatenate([lead, pts.reshape(b - a, -1)], axis=1),
                       fmt=["%d", "%.6f"] + ["%.6f"] * (3 * n), delimiter="\t")
    return tmp.replace(path)


def _block(v, a, b, rate):
    """Frames [a, b): 12 smooth sources (Gaussian bumps moving sinusoidally) plus 0.05 mm
    noise, as dense_face.dense_points, seeded per block start."""
    rng = np.random.default_rng(0)
    n_sources, n = 12, len(v)
    centres = v[rng.integers(0, n, n_sources)]
    sigma = rng.uniform(15.0, 40.0, n_sources)
    W = np.exp(-((v[None] - centres[:, None]) ** 2).sum(-1) / (2 * sigma[:, None] ** 2))
    d = rng.standard_normal((n_sources, 3))
    d *= rng.uniform(1.0, 4.0, (n_sources, 1)) / np.linalg.norm(d, axis=1, keepdims=True)
    fields = W[:, :, None] * d[:, None, :]
    freq = rng.uniform(0.3, 4.0, n_sources)
    phase = rng.uniform(0, 2 * np.pi, n_sources)
    t = np.arange(a, b) / rate
    src = np.sin(2 * np.pi * freq[None] * t[:, None] + phase[None])
    blk = v[None] + np.tensordot(src, fields, axes=1)
    blk += 0.05 * np.random.default_rng([0, a]).standard_normal(blk.shape)
    return blk


def vm_hwm_mib() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def child(*args) -> dict:
    """This file with ``--worker args`` in a child process: its JSON and peak RSS (MiB)."""
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker",
                        *map(str, args)], stdout=subprocess.PIPE, env=os.environ.copy())
    if p.returncode != 0:
        raise RuntimeError(f"worker {args} failed ({p.returncode})")
    return json.loads(p.stdout.decode().strip().splitlines()[-1])


def worker(kind: str, path: str, fmt: str, max_gib: str, k_max: str = "0",
           threads: str = "1") -> dict:
    t0 = time.perf_counter()
    if kind == "ours":
        import logging

        from facemotion.ingest.streaming import stream_dataset
        from facemotion.ranking.qr import rank_from_gram

        logging.disable(logging.WARNING)
        out = Path(path).with_suffix(".A.npz")
        ds = stream_dataset([path], fmt, out, train=[0], heldout=[], max_gib=float(max_gib))
        t_load = time.perf_counter() - t0
        # from here on what the workflow's evaluate_stream job holds: the Gram and the ranking,
        # not the load's frame-by-marker masks (a job of its own there)
        gram, rows, labels = ds.gram, ds.train_rows, ds.labels
        del ds
        rk = rank_from_gram(gram, rows, labels)
        del gram
        t_rank = time.perf_counter() - t0 - t_load
        res = {"load_s": t_load, "rank_s": t_rank, "r1": float(rk.r[0])}
        if int(k_max):
            t1 = time.perf_counter()
            curve = heldout_curve(out, rk, int(k_max), int(threads))
            res.update(curve_s=time.perf_counter() - t1,
                       curve_k=int(curve["k"].iloc[-2]),
                       median_k1=float(curve["median_abs_error_mm"].iloc[0]))
    elif kind == "pandas":
        import pandas as pd

        df = pd.read_csv(path, sep="\t", skiprows=6, header=None, engine="c")
        res = {"rows": len(df)}
    elif kind == "ezc3d":
        import ezc3d

        c = ezc3d.c3d(path)
        res = {"frames": int(c["data"]["points"].shape[2])}
    elif kind.startswith("parse_"):
        res = {"mb": parse_only(kind[len("parse_"):], path) / 1e6}
    elif kind in ("arrow_read", "arrow_open"):
        from pyarrow import csv

        opts = (csv.ReadOptions(skip_rows=6, autogenerate_column_names=True),
                csv.ParseOptions(delimiter="\t"))
        if kind == "arrow_read":
            res = {"rows": csv.read_csv(path, *opts).num_rows}
        else:
            res = {"rows": sum(b.num_rows for b in csv.open_csv(path, *opts))}
    res["wall_s"] = time.perf_counter() - t0
    if kind == "ours":  # the benchmark's housekeeping, not timed (deleting 1 GB takes ~0.5 s)
        out.unlink()
    res["peak_rss_mib"] = vm_hwm_mib()
    return res


#: The parsers judged on each TRC case (``--parsers``): the data section read in blocks of
#: whole lines (the block reader's 16 MiB), each block parsed into one (lines x fields) array:
#: pandas' C parser, numpy's loadtxt, pyarrow's read_csv on one thread (the block reader's
#: three) and on every thread ("arrow_ranges"); pyarrow's open_csv streams the whole section.
PARSERS = ("pandas_blocks", "loadtxt_blocks", "arrow_blocks", "arrow_ranges", "arrow_open")


def heldout_curve(path: Path, rk, k_max: int, threads: int = 1):
    """The error curve of the take's last HELDOUT_SHARE of frames (read in blocks from the
    displacements file the load wrote) for k = 1..k_max, by the streamed curve. Those frames
    are in the Gram too (one take: the streamed loader cannot hold part of it out), so the
    errors are in-sample; the work is that of a held-out curve of as many frames. ``threads``
    share each block's tiles."""
    from facemotion.ingest.displacement_file import RowBlocks, open_displacements
    from facemotion.regions.streamed_curve import streamed_error_curve

    f = open_displacements(path)
    frames = f.shape[0] // 3
    held = RowBlocks(f, [(3 * (frames - round(HELDOUT_SHARE * frames)), f.shape[0])])
    return streamed_error_curve(rk, held.blocks, f.labels, k_max=k_max, threads=threads)


def parse_only(parser: str, path: str) -> int:
    """Parse the data section of a TRC file by ``parser`` (no checks); the bytes parsed."""
    from facemotion.io import trc_blocks

    tb = trc_blocks.open_trc_blocks(path)
    ncol, total = tb.ncol, 0
    if parser == "arrow_open":
        import pyarrow as pa
        from pyarrow import csv

        names = [f"c{i}" for i in range(ncol)]
        opts = (csv.ReadOptions(column_names=names, use_threads=False, block_size=16 << 20),
                csv.ParseOptions(delimiter="\t", quote_char=False),
                csv.ConvertOptions(column_types=dict.fromkeys(names, pa.float64()),
                                   null_values=[""]))
        with open(path, "rb") as fh:
            fh.seek(tb.offset)
            for batch in csv.open_csv(fh, *opts):
                np.column_stack([c.to_numpy(zero_copy_only=False) for c in batch.columns])
        return os.path.getsize(path) - tb.offset
    for chunk in trc_blocks._line_chunks(Path(path), tb.offset, trc_blocks.BLOCK_BYTES):
        body = chunk.lstrip(b"\n")
        if parser == "pandas_blocks":
            values = trc_blocks._pandas(body, ncol)
        elif parser == "loadtxt_blocks":
            values = trc_blocks._loadtxt(body, ncol)
        elif parser == "arrow_blocks":
            values = trc_blocks._arrow(body, ncol)
        else:
            values = _arrow_block(body, ncol)
        if values is None:
            raise RuntimeError(f"{parser}: a block it does not take")
        total += len(chunk)
    return total


def _arrow_block(chunk: bytes, ncol: int) -> np.ndarray:
    """pyarrow's multithreaded read_csv on one byte range, as one float64 array."""
    import pyarrow as pa
    from pyarrow import csv

    names = [f"c{i}" for i in range(ncol)]
    table = csv.read_csv(pa.py_buffer(chunk),
                         csv.ReadOptions(column_names=names, use_threads=True),
                         csv.ParseOptions(delimiter="\t", quote_char=False),
                         csv.ConvertOptions(column_types=dict.fromkeys(names, pa.float64()),
                                            null_values=[""]))
    return np.column_stack([c.to_numpy() for c in table.columns])


def _parsers(name: str, path: Path, reps: int) -> None:
    """MB/s of each parser on the file's data section (median of ``reps`` child runs)."""
    for parser in PARSERS:
        runs = [child(f"parse_{parser}", path, "trc", 1.0) for _ in range(reps)]
        mbs = float(np.median([r["mb"] / r["wall_s"] for r in runs]))
        row(name, f"parser_{parser}", mbs, "MB/s", "parse only, same file; startup included")


def _baselines(fmt: str, huge: bool, size: int, arrow: bool) -> list[str]:
    """pandas (ezc3d for C3D); with ``arrow``, pyarrow's readers (its read_csv holds about
    three times the file: only below 2 GB)."""
    if fmt == "c3d":
        return ["ezc3d"]
    out = ["pandas"] if huge else []
    if not arrow:
        return out
    try:
        import pyarrow  # noqa: F401

        out += (["arrow_read"] if size < 2e9 else []) + ["arrow_open"]
    except ImportError:
        pass
    return out


def run_case(name: str, max_gib: float, reps: int, huge_baseline: bool, arrow: bool,
             parsers: bool = False, k_max: int = K_MAX, threads: int = THREADS) -> None:
    fmt, n, frames = CASES[name]
    OUT.mkdir(parents=True, exist_ok=True)
    path = write_take(OUT / f"{name}.{fmt}", fmt, n, frames)
    size = path.stat().st_size
    base = _baselines(fmt, name != "trc10g" or huge_baseline, size, arrow)
    runs = {k: [] for k in ["ours", *base]}
    for _ in range(reps):  # interleaved: ours, then each baseline
        for k in runs:
            runs[k].append(child(k, path, fmt, max_gib, k_max, threads))
    note = f"{n} x {frames}, {size / 1e9:.2f} GB, median of {reps}"
    ours = {k: float(np.median([r[k] for r in runs["ours"]])) for k in
            ("wall_s", "peak_rss_mib", "load_s", "curve_s") if k in runs["ours"][0]}
    mem_t, time_t = TARGETS.get(name, (None, None))
    if "curve_s" in ours:
        held = round(HELDOUT_SHARE * frames)
        row(name, "ours_file_to_curve_s", ours["wall_s"], "s",
            f"{note}; file -> r values -> error curve")
        row(name, "ours_load_s", ours["load_s"], "s",
            "file -> checks, fill, A on disk, Gram (stream_dataset)")
        row(name, "ours_curve_s", ours["curve_s"], "s",
            f"error curve k = 1..{k_max} of the last {held} frames (streamed_error_curve, "
            f"{threads} thread{'s' if threads > 1 else ''})")
    else:
        row(name, "ours_file_to_r_s", ours["wall_s"], "s", note)
    row(name, "ours_peak_rss", ours["peak_rss_mib"], "MiB", f"memory.max_gib = {max_gib:g}",
        mem_t and f"<={mem_t:.0f}", None if mem_t is None else ours["peak_rss_mib"] <= mem_t)
    row(name, "ours_peak_rss_over_file", ours["peak_rss_mib"] * 2**20 / size, "x")
    for k in base:
        w = float(np.median([r["wall_s"] for r in runs[k]]))
        m = float(np.median([r["peak_rss_mib"] for r in runs[k]]))
        row(name, f"{k}_s", w, "s", "same file, same run")
        row(name, f"{k}_peak_rss", m, "MiB")
        target = time_t if k in ("pandas", "ezc3d") else None
        ratio = ours["wall_s"] / w
        row(name, f"ours_over_{k}", ratio, "x", "time",
            target and f"<={target:g}", None if target is None else ratio <= target)
    if parsers and fmt == "trc":
        _parsers(name, path, reps)


def fit(max_gib: float, k_max: int = K_MAX, threads: int = THREADS) -> None:
    """Exponents of time and peak RSS against frames (468 points) and points (13,500 frames)."""
    sizes = {"frames": [(468, 13_500), (468, 27_000), (468, 54_000)],
             "points": [(117, 13_500), (234, 13_500), (468, 13_500)]}
    OUT.mkdir(parents=True, exist_ok=True)
    for axis, pairs in sizes.items():
        x, t, m = [], [], []
        for n, frames in pairs:
            path = write_take(OUT / f"fit_{n}x{frames}.trc", "trc", n, frames)
            r = child("ours", path, "trc", max_gib, k_max, threads)
            x.append(frames if axis == "frames" else n)
            t.append(r["wall_s"])
            m.append(r["peak_rss_mib"])
        lx = np.log(x)
        row("fit", f"time_exponent_vs_{axis}", float(np.polyfit(lx, np.log(t), 1)[0]), "",
            f"{axis} {x}; times {[round(v, 2) for v in t]} s")
        row("fit", f"rss_exponent_vs_{axis}", float(np.polyfit(lx, np.log(m), 1)[0]), "",
            f"peak RSS {[round(v) for v in m]} MiB")


def page_table(args, load0, load1) -> str:
    lines = [f"Written by `python benchmarks/bench_stream.py --cases {' '.join(args.cases)}"
             f"{' --fit' if args.fit else ''}{' --arrow' if args.arrow else ''}"
             f"{' --parsers' if args.parsers else ''}"
             f"{f' --k-max {args.k_max}' if args.k_max != K_MAX else ''}"
             f"{f' --threads {args.threads}' if args.threads != THREADS else ''}"
             f"{f' --reps {args.reps}' if args.reps != 1 else ''}"
             f"{f' --block {args.block}' if args.block != 'bench-stream' else ''} "
             f"--page docs/performance.md` on "
             f"{time.strftime('%Y-%m-%d')}: memory.max_gib = {args.max_gib:g}, medians of "
             f"{args.reps}; load average {load0:.2f} at the start, {load1:.2f} at the end.", "",
             "| case | measure | value | unit | target | met | note |",
             "|---|---|---:|---|---|---|---|"]
    for r in ROWS:
        v = r["value"]
        lines.append(f"| {r['case']} | {r['measure']} | {v:.4g} | {r['unit']} | "
                     f"{r['target']} | {r['met']} | {r['note']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--worker":
        print(json.dumps(worker(*argv[1:])))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=["trc468", "trc5023", "c3d65k"],
                    choices=sorted(CASES))
    ap.add_argument("--max-gib", type=float, default=1.0)
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--fit", action="store_true")
    ap.add_argument("--k-max", type=int, default=K_MAX,
                    help="largest k of ours' error curve (0: file -> r values only)")
    ap.add_argument("--threads", type=int, default=THREADS,
                    help="threads of ours' error curve")
    ap.add_argument("--huge-baseline", action="store_true",
                    help="trc10g: also pandas.read_csv (about 13 GiB)")
    ap.add_argument("--arrow", action="store_true",
                    help="also pyarrow's read_csv and open_csv (when installed)")
    ap.add_argument("--parsers", action="store_true",
                    help="TRC cases: also the MB/s of each parser judged (PARSERS)")
    ap.add_argument("--page")
    ap.add_argument("--block", default="bench-stream",
                    help="the page's generated block to replace (the 10 GB case has its own: "
                         "bench-stream-10g)")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    for name in args.cases:
        run_case(name, args.max_gib, args.reps, args.huge_baseline, args.arrow, args.parsers,
                 args.k_max, args.threads)
    if args.fit:
        fit(args.max_gib, args.k_max, args.threads)
    if args.page:
        from rule_times import update_page

        update_page(args.page, page_table(args, load0, os.getloadavg()[0]), args.block)
    return 0


if __name__ == "__main__":
    sys.exit(main())
