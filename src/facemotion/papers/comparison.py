"""The papers' quantitative statements beside the study's own values (``paper_comparison.tsv``).

One row per quantitative statement of Lucero & Munhall (2008, "L&M") and Basu & Pentland (1997,
"B&P"): every cell of L&M's Table I, the text's statements about it, the epsilon-ranks, r56/r57
and the shape of R's decay (Fig. 2), Fig. 3's settling point, Fig. 9's maxima, Fig. 10's trend,
B&P's 99.2 % of variance in 10 modes, the six cells of its Table 1 and their ratios, and the mesh
and DOF counts. Each row names where in the paper the value is, what we measure and in which
output file, its class (prediction, calibration or by construction: ``facemotion.papers.table``)
and the verdict by a rule written before the numbers, two-sided and shown to fail in the tests.

Verdicts: ``reproduced``, ``same shape`` (the pattern holds, the number does not), ``differs``,
and ``not measured`` when the study did not produce the output (e.g. a configuration without the
paper's datasets). The rule of each row is written in its ``rule`` column. Numbers whose scale
depends on a reading of the paper (R's normalisation) are compared as scale-free ratios where
possible.

``python -m facemotion.papers.comparison TABLE.tsv`` prints the table as markdown (Table I as a
grid, the other rows as a list) for the docs (facemotion.study.pages).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.papers.basu_pentland import statements
from facemotion.papers.lucero_munhall import (
    fig2,
    fig3,
    fig9,
    fig10,
    sec3,
    table_i,
    table_i_against_chance,
    table_i_text,
)
from facemotion.papers.table import CLASSES, COLUMNS, LM, VERDICTS, Inputs, Rows


def compare(inp: Inputs) -> pd.DataFrame:
    """The comparison table (``COLUMNS``), one row per statement."""
    return pd.DataFrame(compare_rows(inp).rows, columns=COLUMNS)


def compare_rows(inp: Inputs) -> Rows:
    """The comparison's rows with each row's rule object (``Rows.rules``)."""
    R = Rows(inp.paths or {})
    table_i(R, inp)
    table_i_against_chance(R, inp)
    table_i_text(R, inp)
    sec3(R)
    fig2(R, inp)
    fig3(R, inp)
    fig9(R, inp)
    fig10(R, inp)
    statements(R, inp)
    return R


def read_inputs(paths: Mapping[str, str | None], lip_subject: str = "virtual") -> Inputs:
    """Read the outputs named in ``paths`` (keys: 'selected', 'rank_summary', 'lip_reconstruction',
    'lip_counts', 'lip_seeds', and 'r_values:LABEL', 'stability:LABEL', 'curve:LABEL',
    'trajectory:LABEL', 'coefficients:LABEL'); a missing key or file leaves that input empty."""
    def read(p, **kw):
        if not p or not Path(p).is_file():
            return None
        try:
            return pd.read_csv(p, sep="\t", keep_default_na=False, na_values=[""], **kw)
        except Exception as exc:  # pandas raises many kinds for malformed files
            raise InputError(f"{p}: cannot be read as TSV ({type(exc).__name__})") from None

    def per_label(prefix, **kw):
        out = {}
        for key, p in paths.items():
            if key.startswith(prefix + ":"):
                df = read(p, **kw)
                if df is not None:
                    out[key.split(":", 1)[1]] = df
        return out

    marker_str = {"marker": str}
    return Inputs(
        selected=read(paths.get("selected"), dtype=str),
        rank_summary=read(paths.get("rank_summary"), dtype={"dataset": str,
                                                             "redundant_markers": str}),
        r_values=per_label("r_values", dtype=marker_str),
        stability=per_label("stability", dtype=marker_str),
        curves=per_label("curve"),
        trajectory=per_label("trajectory", dtype=marker_str),
        coefficients_k10=per_label("coefficients", dtype={"main_marker": str}),
        lip_reconstruction=read(paths.get("lip_reconstruction")),
        lip_counts=read(paths.get("lip_counts")),
        lip_seeds=read(paths.get("lip_seeds")),
        paths={k: str(v) for k, v in paths.items() if v},
        lip_subject=lip_subject)


def summary_counts(table: pd.DataFrame) -> pd.DataFrame:
    """Verdict counts per paper, class (predictions first) and part (Table I cells vs the
    other statements)."""
    t = table.copy()
    t["part"] = np.where(t["where"] == "Table I", "Table I cells", "other statements")
    g = t.groupby(["paper", "class", "part", "verdict"]).size().unstack(fill_value=0)
    for v in VERDICTS:
        if v not in g.columns:
            g[v] = 0
    g = g[list(VERDICTS)].reset_index()
    g["_c"] = g["class"].map({c: i for i, c in enumerate(CLASSES)})
    g = g.sort_values(["paper", "_c", "part"], ascending=[False, True, True], kind="stable")
    return g.drop(columns="_c").reset_index(drop=True)


MARK = {"reproduced": "✓", "same shape": "≈", "differs": "✗", "not measured": "–"}


def _table_i_grid(ti: pd.DataFrame) -> list[str]:
    labels = list(dict.fromkeys(s.split(",")[0] for s in ti["statement"]))
    lines = ["", "L&M Table I, paper → ours (✓ the same marker, ✗ another one; the regions "
             "and sets against chance are rows below):", "",
             "| order | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for i in range(1, 17):
        cells = []
        for lab in labels:
            r = ti[ti["statement"] == f"{lab}, pivot {i}"]
            if not len(r):
                cells.append("")
                continue
            r = r.iloc[0]
            p = r["paper_value"].split(" ")[0]
            o = r["our_value"].split(" ")[0] if r["our_value"] else "–"
            cells.append(f"{p} → {o} {MARK[r['verdict']]}")
        lines.append(f"| {i} | " + " | ".join(cells) + " |")
    return lines


def to_markdown(table: pd.DataFrame) -> str:
    """Markdown: verdict counts by class, Table I as a grid (paper -> ours), then the other
    rows."""
    lines = ["Verdicts by class (✓ reproduced, ≈ same shape, ✗ differs, – not measured). Only "
             "predictions test the study; calibration targets were tuned for and rows by "
             "construction follow from arithmetic or the design:", "",
             "| paper | class | rows | reproduced | same shape | differs | not measured |",
             "|---|---|---|---|---|---|---|"]
    for _, r in summary_counts(table).iterrows():
        lines.append(f"| {r['paper']} | {r['class']} | {r['part']} | "
                     + " | ".join(str(int(r[v])) for v in VERDICTS) + " |")
    ti = table[table["where"] == "Table I"]
    if len(ti):
        lines += _table_i_grid(ti)
    rest = table[table["where"] != "Table I"]
    lines += ["", "| # | paper | where | statement | class | paper | ours | verdict |",
              "|---|---|---|---|---|---|---|---|"]
    for _, r in rest.iterrows():
        short = "L&M" if r["paper"] == LM else "B&P"
        lines.append(f"| {r['row']} | {short} | {r['where']} | {r['statement']} | "
                     f"{r['class']} | {r['paper_value']} | {r['our_value']} | "
                     f"{MARK[r['verdict']]} {r['verdict']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Print paper_comparison.tsv as markdown.")
    ap.add_argument("table", help="results/tables/paper_comparison.tsv")
    args = ap.parse_args(argv)
    try:
        t = pd.read_csv(args.table, sep="\t", dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError) as exc:
        print(f"{args.table}: cannot be read ({type(exc).__name__})", file=sys.stderr)
        return 1
    sys.stdout.write(to_markdown(t))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
