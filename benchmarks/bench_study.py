"""Time the full default study from scratch, with a per-rule time table.

    python benchmarks/bench_study.py [--repeat N] [--cores 2] [--configfile FILE]
                                     [--config KEY=VALUE ...] [--page docs/performance.md]

Runs `snakemake` from scratch in a fresh temporary directory N times (default 1) and reports
each run's wall time, the median, and the number of jobs. From the last run it builds the
per-rule table (`benchmarks/rule_times.py`): wall seconds from Snakemake's `benchmark:` files,
CPU seconds and the start-up share from each job's log (every step logs its process's CPU
time and how much of it was spent before the step began: Python, Snakemake's preamble,
imports). Writes benchmarks/out/bench_study.tsv and benchmarks/out/rule_times.md; with
--page, replaces the table between the generated:rule-times markers in that file.

Wall time depends on what else the machine runs; CPU sums much less (they still grow when the
other core is busy, through shared caches and frequency).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from rule_times import read_benchmarks, read_job_cpu, table, update_page  # noqa: E402


def study_root(workdir: Path) -> Path:
    roots = [p for p in (workdir / "results").iterdir() if p.is_dir()]
    if len(roots) != 1:
        raise SystemExit(f"bench_study: expected one study under {workdir}/results, "
                         f"found {[p.name for p in roots]}")
    return roots[0]


def run_once(args, workdir: Path) -> tuple[float, int]:
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"),
           "--directory", str(workdir), "--cores", str(args.cores)]
    if args.configfile:
        cmd += ["--configfile", args.configfile]
    if args.config:
        cmd += ["--config", *args.config]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(proc.stderr[-4000:])
        raise SystemExit(f"bench_study: the study failed after {wall:.1f} s")
    m = re.search(r"(\d+) of (\d+) steps", proc.stderr + proc.stdout)
    return wall, int(m.group(2)) if m else -1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configfile", default=None, help="default: the default study")
    ap.add_argument("--config", nargs="*", default=[], help="--config values for snakemake")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1, help="runs from scratch (median wall)")
    ap.add_argument("--target-s", type=float, default=45.0)
    ap.add_argument("--page", help="replace the per-rule table in this file "
                    "(docs/performance.md)")
    args = ap.parse_args()
    walls, jobs, rules, cpu = [], -1, {}, {}
    load0 = os.getloadavg()[0]
    for i in range(args.repeat):
        with tempfile.TemporaryDirectory(prefix="facemotion-bench-") as tmp:
            wall, jobs = run_once(args, Path(tmp))
            walls.append(wall)
            root = study_root(Path(tmp))
            rules, cpu = read_benchmarks(root), read_job_cpu(root)
        print(f"run {i + 1}/{args.repeat}: {wall:.1f} s wall, {jobs} jobs", flush=True)
    wall = statistics.median(walls)
    name = Path(args.configfile).name if args.configfile else "default study"
    verdict = "ok" if wall <= args.target_s else "MISSED"
    text = table(rules, cpu)
    print(text)
    print(f"full study ({name}, {args.cores} cores): median {wall:.1f} s wall over "
          f"{len(walls)} run(s) ({', '.join(f'{w:.1f}' for w in walls)}), {jobs} jobs; "
          f"target {args.target_s:.0f} s: {verdict}")
    out = REPO / "benchmarks" / "out"
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_study.tsv").write_text(
        "config\tcores\truns\twall_s_median\twall_s_runs\tjobs\ttarget_s\tverdict\n"
        f"{name}\t{args.cores}\t{len(walls)}\t{wall:.1f}\t{','.join(f'{w:.1f}' for w in walls)}"
        f"\t{jobs}\t{args.target_s:.0f}\t{verdict}\n")
    (out / "rule_times.md").write_text(text + "\n")
    if args.page:
        load = os.getloadavg()
        head = (f"Written by `python benchmarks/bench_study.py --repeat {args.repeat} --page "
                f"docs/performance.md` (part of `make bench`) on {time.strftime('%Y-%m-%d')}: "
                "the "
                f"{name} from scratch with `--cores {args.cores}`, {len(walls)} run(s) of "
                f"{jobs} jobs: {', '.join(f'{w:.1f}' for w in walls)} s wall, **median "
                f"{wall:.1f} s** (target {args.target_s:.0f} s: {verdict}); load average "
                f"{load0:.2f} before the first run, {load[0]:.2f} after the last. The table is "
                "the last run's.")
        update_page(args.page, head + "\n\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
