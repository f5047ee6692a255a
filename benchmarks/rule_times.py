"""Per-rule time table of a study, from Snakemake's `benchmark:` files and the jobs' logs.

    python benchmarks/rule_times.py [results/paper] [--page docs/performance.md]

Every rule that runs a script writes ``results/<study>/benchmarks/<rule>/<job>.tsv``
(Snakemake's benchmark record; its wall seconds ``s`` are used), and every step logs its
process's CPU seconds and how many of them passed before the step began (Python, Snakemake's
preamble, imports: the start-up), in ``results/<study>/logs/``. This prints, per rule: jobs,
wall seconds (sum, mean, max), CPU seconds (sum) and start-up seconds (sum), and the totals;
with ``--page`` it replaces the table between the markers ``<!-- generated:rule-times:start -->``
and ``<!-- generated:rule-times:end -->`` in that file.
"""

from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from pathlib import Path

DONE = re.compile(r"done: ([\d.]+) s CPU, of which ([\d.]+) s start-up"
                  r"(?:.*?and ([\d.]+) s CPU in child processes)?"
                  r"(?:; peak memory ([\d.]+) MB \(largest child process ([\d.]+) MB\))?")


def read_benchmarks(root: Path) -> dict[str, list[float]]:
    """rule -> wall seconds of each of its jobs (the last record of each benchmark file)."""
    rules: dict[str, list[float]] = {}
    for f in sorted((Path(root) / "benchmarks").glob("*/*.tsv")):
        with open(f, newline="") as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
        if rows:
            rules.setdefault(f.parent.name, []).append(float(rows[-1]["s"]))
    return rules


def read_job_cpu(root: Path) -> dict[str, list[tuple[float, float, float]]]:
    """rule -> (CPU s, start-up CPU s, peak memory MB) of each of its jobs, from the jobs'
    logs (CPU s: the job's process and its child processes; peak memory: the larger of the
    job's process and its largest child process, NaN in logs without it)."""
    out: dict[str, list[tuple[float, float]]] = {}
    logs = Path(root) / "logs"
    for f in sorted(logs.rglob("*.log")):
        found = DONE.findall(f.read_text(errors="replace"))
        if not found:
            continue
        rel = f.relative_to(logs)
        rule = rel.parts[0] if len(rel.parts) > 1 else f.stem
        cpu, startup, children, own_mb, child_mb = found[-1]
        peak = max(float(own_mb), float(child_mb)) if own_mb else float("nan")
        # the job's own CPU and its children's (worker processes, the MP4 encoder)
        out.setdefault(rule, []).append((float(cpu) + float(children or 0), float(startup),
                                         peak))
    return out


def table(rules: dict[str, list[float]],
          cpu: dict[str, list[tuple[float, float, float]]]) -> str:
    def fmt(x):
        return "" if math.isnan(x) else f"{x:.1f}"

    lines = ["| rule | jobs | wall s (sum) | wall s (mean) | wall s (max) | CPU s (sum, with "
             "child processes) | of which start-up | peak memory MB (max) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    tot_jobs = tot_wall = tot_cpu = tot_start = 0.0
    for r in sorted(rules, key=lambda r: -sum(rules[r])):
        walls = rules[r]
        c = cpu.get(r, [])
        cs = sum(x for x, _, _ in c) if c else float("nan")
        st = sum(y for _, y, _ in c) if c else float("nan")
        mem = max((m for _, _, m in c), default=float("nan"))
        lines.append(f"| `{r}` | {len(walls)} | {sum(walls):.1f} | {sum(walls) / len(walls):.2f} "
                     f"| {max(walls):.2f} | {fmt(cs)} | {fmt(st)} | "
                     f"{'' if math.isnan(mem) else f'{mem:.0f}'} |")
        tot_jobs += len(walls)
        tot_wall += sum(walls)
        tot_cpu += 0 if math.isnan(cs) else cs
        tot_start += 0 if math.isnan(st) else st
    lines.append(f"| **all** | {int(tot_jobs)} | {tot_wall:.1f} | | | {tot_cpu:.1f} "
                 f"| {tot_start:.1f} | |")
    return "\n".join(lines)


def replace_between_markers(text: str, new: str, name: str = "rule-times") -> str:
    """``text`` with what lies between ``<!-- generated:name:start -->`` and
    ``<!-- generated:name:end -->`` replaced by ``new`` (every benchmark writes its table in
    docs/performance.md this way; ``facemotion docs --check`` skips these blocks)."""
    start, end = f"<!-- generated:{name}:start -->", f"<!-- generated:{name}:end -->"
    if start not in text or end not in text:
        raise SystemExit(f"benchmarks: markers {start} ... {end} not found")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n\n{new}\n\n{end}{tail}"


def update_page(path, new: str, name: str = "rule-times") -> None:
    """Replace the table between the ``name`` markers of the file at ``path`` with ``new``."""
    p = Path(path)
    p.write_text(replace_between_markers(p.read_text(), new, name))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default="results/paper",
                    help="the study's results folder (default results/paper)")
    ap.add_argument("--page", help="replace the table between the markers in this file "
                    "(docs/performance.md)")
    args = ap.parse_args(argv)
    rules = read_benchmarks(Path(args.root))
    if not rules:
        print(f"rule_times: no benchmark files under {args.root}/benchmarks", file=sys.stderr)
        return 1
    text = table(rules, read_job_cpu(Path(args.root)))
    print(text)
    if args.page:
        update_page(args.page, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
