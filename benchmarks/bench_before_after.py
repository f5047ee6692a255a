"""The default study from scratch, this code against an earlier commit, in one sitting.

    python benchmarks/bench_before_after.py [--before REV] [--repeat N] [--cores 2]
                                            [--page docs/performance.md]

Checks out ``--before`` (default: the last commit before one job per dataset, when every stage
was one job over all datasets) into a temporary git worktree and runs the default study from
scratch in a fresh directory with each code in turn, before, after, before, after ... (N runs
each), with the same Python, Snakemake and profile; each run's own package comes first on
PYTHONPATH. Both read the shared data from the same folder. Reports each run's wall time and
CPU time (user + system of Snakemake and every job), the medians and the ratio after / before
of the medians, and the job counts. With --page, writes the table between the
``generated:restructure`` markers of that page.

The machine's speed drifts over minutes; alternating the two codes puts the drift on both.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: The last commit in which every stage was one job over all datasets.
BEFORE = "be321ac"
MARKER = "restructure"


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_study(code: Path, workdir: Path, cores: int, shared: Path) -> tuple[float, float, int]:
    """(wall s, CPU s, jobs) of the default study with the code in ``code``."""
    env = dict(os.environ, PYTHONPATH=str(code / "src"))
    cmd = [sys.executable, "-m", "snakemake", "-s", str(code / "Snakefile"), "--directory",
           str(workdir), "--cores", str(cores), "--config", f"shared_data={shared}"]
    cpu0, t0 = children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall, cpu = time.perf_counter() - t0, children_cpu() - cpu0
    if proc.returncode != 0:
        print(proc.stderr[-4000:])
        raise SystemExit(f"bench_before_after: the study with {code} failed")
    m = re.search(r"(\d+) of (\d+) steps", proc.stderr + proc.stdout)
    return wall, cpu, int(m.group(2)) if m else -1


def write_block(page: Path, name: str, text: str) -> None:
    start, end = f"<!-- generated:{name}:start -->", f"<!-- generated:{name}:end -->"
    body = page.read_text()
    if start not in body or end not in body:
        raise SystemExit(f"{page}: no {start} ... {end} block to write")
    head, rest = body.split(start, 1)
    _, tail = rest.split(end, 1)
    page.write_text(f"{head}{start}\n{text.rstrip()}\n{end}{tail}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=BEFORE, help=f"the earlier commit (default {BEFORE})")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each code (default 3)")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--shared-data", default=os.environ.get("FACEMOTION_SHARED_DATA")
                    or str(REPO.parent / "shared" / "data"))
    ap.add_argument("--page", help="write the table into this page's restructure block")
    args = ap.parse_args()
    rev = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", args.before],
                         capture_output=True, text=True, check=True).stdout.strip()
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--", "src",
                            "scripts", "workflow", "Snakefile"],
                           capture_output=True, text=True, check=True).stdout.strip()
    shared = Path(args.shared_data).resolve()
    runs: dict[str, list[tuple[float, float, int]]] = {"before": [], "after": []}
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="facemotion-before-") as tmp:
        old = Path(tmp) / "code"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(old),
                        rev], check=True)
        try:
            for i in range(args.repeat):
                for which, code in (("before", old), ("after", REPO)):
                    with tempfile.TemporaryDirectory(prefix="facemotion-run-") as work:
                        runs[which].append(run_study(code, Path(work), args.cores, shared))
                    wall, cpu, jobs = runs[which][-1]
                    print(f"run {i + 1}/{args.repeat} {which}: {wall:.1f} s wall, "
                          f"{cpu:.1f} s CPU, {jobs} jobs", flush=True)
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(old)],
                           check=False)
    med = {w: (statistics.median(r[0] for r in runs[w]),
               statistics.median(r[1] for r in runs[w])) for w in runs}
    jobs = {w: runs[w][-1][2] for w in runs}
    ratio_wall = med["after"][0] / med["before"][0]
    ratio_cpu = med["after"][1] / med["before"][1]
    after_name = f"`{head}`" + (" plus uncommitted changes" if dirty else "")
    rows = [
        f"| | before (`{rev}`) | after ({after_name}) | after / before |",
        "|---|---|---|---|",
        f"| jobs | {jobs['before']} | {jobs['after']} | |",
        "| wall, each run (s) | {} | {} | |".format(
            ", ".join(f"{r[0]:.1f}" for r in runs["before"]),
            ", ".join(f"{r[0]:.1f}" for r in runs["after"])),
        f"| wall, median (s) | {med['before'][0]:.1f} | {med['after'][0]:.1f} | "
        f"**{ratio_wall:.2f}** |",
        f"| CPU, median (s) | {med['before'][1]:.1f} | {med['after'][1]:.1f} | "
        f"{ratio_cpu:.2f} |",
    ]
    load = os.getloadavg()[0]
    text = (f"Written by `python benchmarks/bench_before_after.py --repeat {args.repeat} "
            f"--page docs/performance.md` on {time.strftime('%Y-%m-%d %H:%M')}, "
            f"{os.cpu_count()} CPUs, `--cores {args.cores}`, runs alternating before and "
            f"after; load average {load0:.2f} before the first run, {load:.2f} after the "
            "last. CPU is user + system time of Snakemake and every job.\n\n"
            + "\n".join(rows))
    print(text)
    if args.page:
        write_block(Path(args.page), MARKER, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
