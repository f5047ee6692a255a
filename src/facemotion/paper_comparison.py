"""The papers' quantitative statements beside the study's own values (``paper_comparison.tsv``).

One row per quantitative statement of Lucero & Munhall (2008, "L&M") and Basu & Pentland (1997,
"B&P"): every cell of L&M's Table I, the text's statements about it, the epsilon-ranks, r56/r57
and the shape of R's decay (Fig. 2), Fig. 3's settling point, Fig. 9's maxima, Fig. 10's trend,
B&P's 99.2 % of variance in 10 modes, the six cells of its Table 1 and their ratios, and the mesh
and DOF counts. Each row names where in the paper the value is, what we measure and in which
output file, the verdict by a stated rule, and whether the row was a calibration target of the
virtual talkers (then agreement is by construction, not a finding).

Verdicts: ``reproduced``, ``same shape`` (the pattern holds, the number does not), ``differs``,
and ``not measured`` when the study did not produce the output (e.g. a configuration without the
paper's datasets). The rule of each row is written in its ``rule`` column. Numbers whose scale
depends on a reading of the paper (R's normalisation) are compared as scale-free ratios where
possible.

``python -m facemotion.paper_comparison TABLE.tsv`` prints the table as markdown (Table I as a
grid, the other rows as a list) for the README.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.synth import REGIONS

COLUMNS = ["row", "paper", "where", "statement", "paper_value", "our_value", "measure",
           "output", "verdict", "rule", "calibration"]
VERDICTS = ("reproduced", "same shape", "differs", "not measured")
LM = "Lucero & Munhall 2008"
BP = "Basu & Pentland 1997"

# L&M Table I: the first 16 columns (markers) selected by QR with column pivoting.
TABLE_I = {
    "S1": [40, 34, 38, 2, 36, 6, 20, 49, 11, 52, 54, 47, 22, 32, 39, 48],
    "S2a": [40, 34, 13, 38, 47, 42, 6, 56, 11, 36, 48, 39, 52, 20, 49, 14],
    "S2b": [40, 34, 13, 38, 48, 47, 11, 36, 42, 49, 6, 53, 20, 39, 56, 14],
    "S2a*": [40, 34, 13, 42, 38, 43, 47, 11, 36, 6, 49, 12, 48, 16, 20, 52],
    "S2b*": [40, 34, 11, 38, 56, 42, 6, 47, 13, 36, 12, 48, 39, 16, 53, 20],
}
S2_LABELS = ("S2a", "S2b", "S2a*", "S2b*")
LOWER_RIGHT = ("42", "43", "47", "48", "56")       # L&M Sec. IV: "lower-right portion"
FIG9_MAX_MM = {"x": 0.8, "y": 2.0, "z": 0.9}        # L&M Fig. 9, Sec. V
# B&P Table 1: reconstruction error per DOF in the model's normalised units
BP_TABLE_1 = {("xyz_8_points", "10_modes"): 1.10e-3, ("xyz_8_points", "full_covariance"): 7.80e-4,
              ("yz_all_points", "10_modes"): 7.13e-4, ("yz_all_points", "full_covariance"): 4.38e-4,
              ("xy_all_points", "10_modes"): 6.70e-3, ("xy_all_points", "full_covariance"): 7.50e-3}
BP_VIEW = {"xyz_8_points": "xyz of 8 points", "yz_all_points": "yz of all points",
           "xy_all_points": "xy of all points"}

RULE_MARKER = ("reproduced: the same marker; same shape: a marker of the same face region "
               "(the virtual talker's regions, synth.REGIONS, applied to the paper's numbers); "
               "differs: otherwise")
RULE_1_5 = "reproduced: within 1.5x of the paper's value; same shape: within 3x; differs: beyond"
RULE_1_5_10 = ("reproduced: within 1.5x of the paper's value; same shape: within 10x (the same "
               "order of magnitude); differs: beyond")
RULE_EXACT = "reproduced: equal; differs: otherwise"


def region(marker) -> str:
    """Face region of a marker number in the virtual talker's layout ('?' if none)."""
    for name, labels in REGIONS.items():
        if str(marker) in labels:
            return name
    return "?"


def factor_verdict(ours: float, paper: float, near: float, far: float) -> str:
    """reproduced within ``near``x, same shape within ``far``x, differs beyond."""
    if ours is None or not np.isfinite(ours):
        return "not measured"
    if ours <= 0 or paper <= 0:
        return "differs"
    f = max(ours / paper, paper / ours)
    return "reproduced" if f <= near else "same shape" if f <= far else "differs"


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        v = float(v)
        if not np.isfinite(v):
            return str(v)
        if v != 0 and (abs(v) >= 1e4 or abs(v) < 1e-2):
            return f"{v:.3g}"
        return f"{v:.3g}" if abs(v) < 10 else f"{v:.1f}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


@dataclass
class Inputs:
    """The outputs the comparison reads; any may be absent (``None``)."""

    selected: pd.DataFrame | None = None              # tables/selected_markers.tsv
    rank_summary: pd.DataFrame | None = None          # tables/rank_summary.tsv
    r_values: Mapping[str, pd.DataFrame] | None = None        # label -> qr/r_values.tsv
    stability: Mapping[str, pd.DataFrame] | None = None       # label -> qr/stability.tsv
    curves: Mapping[str, pd.DataFrame] | None = None          # label -> eval/error_curve.tsv
    trajectory: Mapping[str, pd.DataFrame] | None = None      # label -> eval/trajectory_errors
    coefficients_k10: Mapping[str, pd.DataFrame] | None = None  # label -> fit/coefficients_k10
    lip_reconstruction: pd.DataFrame | None = None    # lips/{subject}/reconstruction.tsv
    lip_counts: pd.DataFrame | None = None            # lips/{subject}/model_counts.tsv
    paths: Mapping[str, str] | None = None            # what -> output path (for the table)
    tolerance_mm: float = 0.5
    lip_subject: str = "virtual"


class _Rows:
    def __init__(self, paths: Mapping[str, str]):
        self.rows: list[dict] = []
        self.paths = dict(paths or {})

    def add(self, paper, where, statement, paper_value, our_value, measure, output, verdict,
            rule, calibration):
        if verdict not in VERDICTS:
            raise ValueError(verdict)
        self.rows.append({
            "row": len(self.rows) + 1, "paper": paper, "where": where, "statement": statement,
            "paper_value": _fmt(paper_value), "our_value": _fmt(our_value), "measure": measure,
            "output": self.paths.get(output, output), "verdict": verdict, "rule": rule,
            "calibration": "yes" if calibration else "no"})


def _get(mapping, key):
    return None if mapping is None else mapping.get(key)


# ---------------------------------------------------------------------------------------- L&M


def _table_i(R: _Rows, inp: Inputs) -> None:
    sel = inp.selected
    for label, paper_col in TABLE_I.items():
        ours_col = (None if sel is None or label not in sel.columns
                    else [str(m) for m in sel[label].fillna("").astype(str)])
        for i, pm in enumerate(paper_col):
            pm = str(pm)
            om = ours_col[i] if ours_col is not None and i < len(ours_col) else None
            if not om:
                verdict, ours = "not measured", None
            elif om == pm:
                verdict, ours = "reproduced", f"{om} ({region(om)})"
            elif region(om) == region(pm):
                verdict, ours = "same shape", f"{om} ({region(om)})"
            else:
                verdict, ours = "differs", f"{om} ({region(om)})"
            R.add(LM, "Table I", f"{label}, pivot {i + 1}", f"{pm} ({region(pm)})", ours,
                  "marker selected at this pivot order (first 30 sentences; S2a*, S2b*: last 30)",
                  "selected", verdict, RULE_MARKER, False)


def _pivots(inp: Inputs, label: str) -> list[str] | None:
    sel = inp.selected
    if sel is None or label not in sel.columns:
        return None
    return [str(m) for m in sel[label].fillna("").astype(str) if str(m)]


def _table_i_text(R: _Rows, inp: Inputs) -> None:
    cols = {lab: _pivots(inp, lab) for lab in TABLE_I}
    have = {lab: c for lab, c in cols.items() if c}
    measure = "pivot order of the named markers in Table I's datasets"

    def n_a(statement, paper_value, rule):
        R.add(LM, "Sec. IV, Table I", statement, paper_value, None, measure, "selected",
              "not measured", rule, False)

    rule = "reproduced: every dataset; same shape: all but one; differs: otherwise"
    if len(have) == len(TABLE_I):
        firsts = [c[0] for c in have.values()]
        hits = sum(f == "40" for f in firsts)
        v = "reproduced" if hits == 5 else "same shape" if hits == 4 else "differs"
        R.add(LM, "Sec. IV, Table I", "first pivot is 40 (lower-lip centre) in every dataset",
              "40 in all 5", ", ".join(firsts), measure, "selected", v, rule, False)
        seconds = [c[1] for c in have.values()]
        hits = sum(s == "34" for s in seconds)
        corner = sum(s in ("34", "38") for s in seconds)
        v = ("reproduced" if hits == 5 else "same shape" if corner == 5 else "differs")
        R.add(LM, "Sec. IV, Table I", "second pivot is 34 (left lip corner) in every dataset",
              "34 in all 5", ", ".join(seconds), measure, "selected", v,
              "reproduced: 34 in all five; same shape: a lip corner (34 or 38) in all five; "
              "differs: otherwise", False)
    else:
        n_a("first pivot is 40 (lower-lip centre) in every dataset", "40 in all 5", rule)
        n_a("second pivot is 34 (left lip corner) in every dataset", "34 in all 5", rule)
    s1 = cols.get("S1")
    rule = ("reproduced: the same four markers at pivots 3-6; same shape: the same regions; "
            "differs: otherwise")
    if s1:
        ours = s1[2:6]
        paper = ["38", "2", "36", "6"]
        v = ("reproduced" if sorted(ours) == sorted(paper) else "same shape"
             if sorted(map(region, ours)) == sorted(map(region, paper)) else "differs")
        R.add(LM, "Sec. IV, Table I", "S1 pivots 3-6: right corner, right brow, upper lip, "
              "left brow", "38, 2, 36, 6", ", ".join(ours), measure, "selected", v, rule, False)
    else:
        n_a("S1 pivots 3-6: right corner, right brow, upper lip, left brow", "38, 2, 36, 6",
            rule)
    s2 = {lab: have[lab] for lab in S2_LABELS if lab in have}
    rule = ("reproduced: an eyelid marker (11 or 13) at pivot 3 in all four S2 datasets; same "
            "shape: one among the first 6 in all four; differs: otherwise")
    if len(s2) == 4:
        pos = [min([c.index(m) + 1 for m in ("11", "13") if m in c] or [99]) for c in s2.values()]
        v = ("reproduced" if all(p == 3 for p in pos) else "same shape"
             if all(p <= 6 for p in pos) else "differs")
        R.add(LM, "Sec. IV, Table I", "S2: an eyelid (13 or 11) third", "3, 3, 3, 3",
              ", ".join(map(str, pos)), "pivot order of the first eyelid marker (11 or 13), "
              "S2a, S2b, S2a*, S2b*", "selected", v, rule, False)
        counts = [sum(m in LOWER_RIGHT for m in c[:8]) for c in s2.values()]
        v = ("reproduced" if all(n >= 2 for n in counts) else "same shape"
             if all(n >= 1 for n in counts) else "differs")
        R.add(LM, "Sec. IV, Table I", "S2: lower-right face markers (42, 43, 47, 48, 56) early",
              "3, 2, 3, 3", ", ".join(map(str, counts)),
              "how many of 42, 43, 47, 48, 56 are among the first 8 pivots, S2a, S2b, S2a*, "
              "S2b*", "selected",
              v, "reproduced: at least 2 in each S2 dataset; same shape: at least 1 in each; "
              "differs: otherwise", False)
        pos = [c.index("36") + 1 if "36" in c else 99 for c in s2.values()]
        v = ("reproduced" if all(8 <= p <= 10 for p in pos) else "same shape"
             if all(5 <= p <= 13 for p in pos) else "differs")
        R.add(LM, "Sec. IV, Table I", "S2: the upper-lip marker (36) appears later, 8th-10th",
              "10, 8, 9, 10", ", ".join(map(str, pos)),
              "pivot order of 36 in S2a, S2b, S2a*, S2b*", "selected", v,
              "reproduced: 8th-10th in all four; same shape: 5th-13th in all four; differs: "
              "otherwise", False)
    else:
        for st, pv in (("S2: an eyelid (13 or 11) third", "3, 3, 3, 3"),
                       ("S2: lower-right face markers (42, 43, 47, 48, 56) early", "3, 2, 3, 3"),
                       ("S2: the upper-lip marker (36) appears later, 8th-10th",
                        "10, 8, 9, 10")):
            n_a(st, pv, "see the statement")
    # S1: the last pivot is 13, the copied eyelid
    rv = _get(inp.r_values, "S1")
    rule = ("reproduced: 13 last; same shape: 11 last (13 and 11 are identical where 13 was "
            "copied, so which of the two QR meets second is a tie); differs: otherwise")
    if rv is not None:
        last = str(rv.sort_values("order")["marker"].astype(str).iloc[-1])
        v = "reproduced" if last == "13" else "same shape" if last == "11" else "differs"
        R.add(LM, "Sec. IV", "S1: the last selected marker is 13 (left upper eyelid)",
              "13 (eyelids)", f"{last} ({region(last)})", "last pivot of S1 (first 30 sentences)",
              "r_values:S1", v, rule, True)
    else:
        R.add(LM, "Sec. IV", "S1: the last selected marker is 13 (left upper eyelid)",
              "13 (eyelids)", None, "last pivot of S1", "r_values:S1", "not measured", rule,
              True)
    X = _get(inp.coefficients_k10, "S1")
    rule = ("reproduced: 13 secondary with a coefficient within 0.05 of 1 on main marker 11; "
            "same shape: the same within 0.2, or 11 secondary on main marker 13 within 0.05 "
            "(QR met the identical pair the other way round); differs: otherwise")
    coef, orient = None, ""
    if X is not None:
        mains = X["main_marker"].astype(str)
        for main, sec in (("11", "13"), ("13", "11")):
            if sec in X.columns and (mains == main).any():
                coef = float(X.loc[mains == main, sec].iloc[0])
                orient = f"{sec} on {main}"
                break
    statement = "S1: marker 13's fit coefficient on 11 (basis of ten)"
    measure = ("X = R11^-1 R12 at k = 10: coefficient of the secondary eyelid marker on the "
               "main one")
    if coef is None:
        R.add(LM, "Sec. IV, Fig. 4", statement, 1.0, None, measure, "coefficients:S1",
              "not measured", rule, True)
    else:
        d = abs(coef - 1.0)
        if orient == "13 on 11":
            v = "reproduced" if d <= 0.05 else "same shape" if d <= 0.2 else "differs"
        else:
            v = "same shape" if d <= 0.05 else "differs"
        R.add(LM, "Sec. IV, Fig. 4", statement, "1 (13 on 11)", f"{coef:.3f} ({orient})",
              measure, "coefficients:S1", v, rule, True)


def _fig2(R: _Rows, inp: Inputs) -> None:
    tol = inp.tolerance_mm
    rs = inp.rank_summary
    paper_ranks = {"S1": 56, "S2a": 57, "S2b": 57}
    for label, pr in paper_ranks.items():
        our = None
        norm = ""
        if rs is not None:
            sub = rs[(rs["dataset"].astype(str) == label)
                     & np.isclose(rs["tolerance_mm"].astype(float), tol)]
            if len(sub):
                our = int(sub["epsilon_rank"].iloc[0])
                norm = str(sub["r_normalisation"].iloc[0]) if "r_normalisation" in sub else ""
        v = "not measured" if our is None else "reproduced" if our == pr else "differs"
        R.add(LM, "Sec. IV, Fig. 2", f"{label}: epsilon-rank at epsilon = {tol:g} mm", pr, our,
              f"smallest k with ||R22||_2 <= epsilon (Sec. III), R normalisation '{norm}'",
              "rank_summary", v, RULE_EXACT, label == "S1")
    # S1's sudden drop: r56, r57 and their ratio
    rv = _get(inp.r_values, "S1")
    measure_norm = ("|r_kk| under the study's R normalisation"
                    + (f" ('{rv['r_normalisation'].iloc[0]}')" if rv is not None
                       and "r_normalisation" in rv else ""))
    r = None if rv is None else rv.sort_values("order")["r_normalised"].to_numpy(float)
    if r is not None and len(r) >= 57:
        ratio = r[55] / r[56] if r[56] > 0 else math.inf
        v = "reproduced" if ratio >= 50 else "same shape" if ratio >= 5 else "differs"
        R.add(LM, "Sec. IV, Fig. 2", "S1: r56/r57, a sudden drop for the last value",
              22.70 / 0.10, ratio, "r56 / r57 (scale-free)", "r_values:S1", v,
              "reproduced: >= 50 (calibration target; an exact copy makes r57 numerically 0); "
              "same shape: >= 5; differs: otherwise", True)
        R.add(LM, "Sec. IV, Fig. 2", "S1: r56 (mm)", 22.70, r[55], measure_norm, "r_values:S1",
              factor_verdict(r[55], 22.70, 1.5, 3.0), RULE_1_5, False)
        v = ("reproduced" if factor_verdict(r[56], 0.10, 1.5, 1.5) == "reproduced"
             else "same shape" if r[56] <= tol else "differs")
        R.add(LM, "Sec. IV, Fig. 2", "S1: r57 (mm)", 0.10, r[56], measure_norm, "r_values:S1",
              v, f"reproduced: within 1.5x; same shape: below epsilon = {tol:g} mm (the rank "
              "test passes); differs: otherwise", True)
    else:
        for st, pv in (("S1: r56/r57, a sudden drop for the last value", 227.0),
                       ("S1: r56 (mm)", 22.70), ("S1: r57 (mm)", 0.10)):
            R.add(LM, "Sec. IV, Fig. 2", st, pv, None, measure_norm, "r_values:S1",
                  "not measured", RULE_1_5, True)
    for label in ("S2a", "S2b"):
        rv2 = _get(inp.r_values, label)
        rule = "reproduced: r56/r57 < 1.5 (no drop at the end); differs: otherwise"
        if rv2 is not None and len(rv2) >= 57:
            r2 = rv2.sort_values("order")["r_normalised"].to_numpy(float)
            ratio = r2[55] / r2[56]
            R.add(LM, "Sec. IV, Fig. 2", f"{label}: no gap in the data (no drop at the end)",
                  "no drop", ratio, "r56 / r57 (scale-free)", f"r_values:{label}",
                  "reproduced" if ratio < 1.5 else "differs", rule, False)
        else:
            R.add(LM, "Sec. IV, Fig. 2", f"{label}: no gap in the data (no drop at the end)",
                  "no drop", None, "r56 / r57", f"r_values:{label}", "not measured", rule, False)
    # smooth decay of R (calibration item 2)
    rule = ("reproduced: r50/r10 <= 0.5 and r50/r30 <= 0.9 (still decreasing through the tail, "
            "no knee and flat tail); same shape: r50/r10 <= 0.7; differs: otherwise")
    for label in ("S1", "S2a", "S2b"):
        rv2 = _get(inp.r_values, label)
        if rv2 is not None and len(rv2) >= 50:
            r2 = rv2.sort_values("order")["r_normalised"].to_numpy(float)
            a, b = r2[49] / r2[9], r2[49] / r2[29]
            v = ("reproduced" if a <= 0.5 and b <= 0.9 else "same shape" if a <= 0.7
                 else "differs")
            R.add(LM, "Sec. IV, Fig. 2", f"{label}: R values decrease smoothly",
                  "decrease smoothly", f"r50/r10 = {a:.3f}, r50/r30 = {b:.3f}",
                  "ratios of |r_kk| (scale-free)", f"r_values:{label}", v, rule, True)
        else:
            R.add(LM, "Sec. IV, Fig. 2", f"{label}: R values decrease smoothly",
                  "decrease smoothly", None, "ratios of |r_kk|", f"r_values:{label}",
                  "not measured", rule, True)


def _fig3(R: _Rows, inp: Inputs) -> None:
    rule = ("reproduced: within 5 sentences of 25; same shape: 12-50 sentences; differs: "
            "otherwise")
    for label, st in (("S1", "S1: the first 12 R values stabilise after ~25 sentences"),
                      ("S2a", "S2: similar to S1 (S2a shown)")):
        stab = _get(inp.stability, label)
        our = None
        if stab is not None and len(stab):
            our = int(np.nanmax(stab["settled_sentences"].to_numpy(float)[:12]))
        if our is None:
            v = "not measured"
        else:
            v = ("reproduced" if abs(our - 25) <= 5 else "same shape" if 12 <= our <= 50
                 else "differs")
        R.add(LM, "Sec. IV, Fig. 3", st, 25, our,
              "sentences after which each of the first 12 r values (per coordinate) stays "
              "within 10 % of its value with all 30 (sentences in the given order)",
              f"stability:{label}", v, rule, False)


def _fig9(R: _Rows, inp: Inputs) -> None:
    tr = _get(inp.trajectory, "S1")
    ok = tr is not None and len(tr) and str(tr["marker"].iloc[0]) == "56"
    in_basis = None if not ok else bool(str(tr["in_basis"].iloc[0]).lower() in ("true", "1"))
    sent = None if not ok else str(tr["sentence"].iloc[0])
    k = None if not ok else int(tr["k"].iloc[0])
    R.add(LM, "Sec. V, Fig. 9", "S1: marker 56 (jaw) is a secondary marker of the basis of ten",
          "secondary", None if in_basis is None else ("main" if in_basis else "secondary"),
          f"is 56 among the first k = {k} pivots (sentence {sent})", "trajectory:S1",
          "not measured" if in_basis is None or k != 10
          else "differs" if in_basis else "reproduced", RULE_EXACT, True)
    for axis, pv in FIG9_MAX_MM.items():
        our = None
        if ok and not in_basis and k == 10:
            our = float(tr.loc[tr["axis"] == axis, "max_abs_error_mm"].iloc[0])
        R.add(LM, "Sec. V, Fig. 9", f"S1, sentence 31, marker 56: maximum {axis} error (mm)", pv,
              our, f"largest |measured - model| along {axis}, basis of ten, held-out sentence "
              f"{sent}", "trajectory:S1",
              "not measured" if our is None else factor_verdict(our, pv, 1.5, 3.0), RULE_1_5,
              True)


def _fig10(R: _Rows, inp: Inputs) -> None:
    c = _get(inp.curves, "S1")
    if c is None or len(c) < 31:
        for st in ("S1: the mean error decreases as markers are added",
                   "S1: mean error at k = 10 against k = 1",
                   "S1: the relative error is high because most markers move little"):
            R.add(LM, "Sec. V, Fig. 10", st, "", None, "", "curve:S1", "not measured", "", False)
        return
    c = c.set_index("k").sort_index()
    e = c["mean_abs_error_mm"].loc[1:30].to_numpy(float)
    steps = np.diff(e)
    n_down = int(np.sum(steps < 0))
    v = ("reproduced" if n_down >= 0.9 * len(steps) and e[-1] < e[0] else "same shape"
         if e[-1] < e[0] else "differs")
    R.add(LM, "Sec. V, Fig. 10", "S1: the mean error decreases as markers are added",
          "decreasing (Fig. 10 top; values not printed)", f"falls in {n_down} of {len(steps)} "
          "steps", "mean absolute 3-D error of the secondary markers, held-out sentences 31-40, "
          "k = 1..30", "curve:S1", v, "reproduced: falls in at least 90 % of the steps from "
          "k = 1 to 30; same shape: lower at 30 than at 1; differs: otherwise", False)
    ratio = float(c.loc[10, "mean_abs_error_mm"] / c.loc[1, "mean_abs_error_mm"])
    R.add(LM, "Sec. V, Fig. 10", "S1: mean error at k = 10 against k = 1",
          "falls with k (not printed)", ratio, "mean absolute error at k = 10 / at k = 1",
          "curve:S1", "reproduced" if ratio <= 0.6 else "same shape" if ratio < 1 else "differs",
          "reproduced: <= 0.6 (issue 8's reading of Fig. 10's trend); same shape: < 1; "
          "differs: otherwise", False)
    per, pooled = float(c.loc[10, "rel_error_per_marker"]), float(c.loc[10, "rel_error_pooled"])
    R.add(LM, "Sec. V, Fig. 10", "S1: the relative error is high because most markers move "
          "little", "relative error high (Fig. 10 bottom)",
          f"{per:.2f} per marker vs {pooled:.2f} pooled",
          "at k = 10: relative error averaged over markers against the pooled ratio (sum of "
          "errors / sum of displacements)", "curve:S1",
          "reproduced" if per >= 1.2 * pooled else "differs",
          "reproduced: the per-marker mean is at least 1.2x the pooled ratio (small "
          "displacements inflate it); differs: otherwise", False)


def _sec3(R: _Rows) -> None:
    n = math.comb(57, 10)
    R.add(LM, "Sec. III", "number of 10-marker subsets of 57", 4.32e10, float(n),
          "binomial coefficient C(57, 10)", "computed", factor_verdict(n, 4.32e10, 1.005, 1.005),
          "reproduced: within 0.5 %; differs: otherwise", False)


# ---------------------------------------------------------------------------------------- B&P


def _bp(R: _Rows, inp: Inputs) -> None:
    rec, counts = inp.lip_reconstruction, inp.lip_counts
    ls = inp.lip_subject
    out_rec, out_cnt = f"lip_reconstruction:{ls}", f"lip_counts:{ls}"
    # 99.2 % of the variance in 10 modes
    q = None
    if counts is not None:
        sel = counts[counts["quantity"].astype(str) == "variance_in_modes_percent"]
        if len(sel):
            q = float(sel["our_value"].iloc[0])
    v = ("not measured" if q is None else "reproduced" if abs(q - 99.2) <= 0.5
         else "same shape" if q >= 95 else "differs")
    R.add(BP, "Sec. 5", "the first 10 modes cover 99.2 % of the variance", 99.2, q,
          f"variance of the fitted deformations in the first 10 PCA modes, % ({ls} talker)",
          out_cnt, v, "reproduced: within 0.5 percentage points; same shape: >= 95 %; differs: "
          "otherwise", False)
    # Table 1 cells
    cells: dict[tuple[str, str], float] = {}
    if rec is not None:
        paper_rows = rec[rec["paper_definition"].astype(str).str.lower().isin(["true", "1"])]
        for _, row in paper_rows.iterrows():
            cells[(str(row["view"]), str(row["covariance"]))] = float(
                row["mse_per_dof_model_units2"])
    for (view, cov), pv in BP_TABLE_1.items():
        our = cells.get((view, cov))
        R.add(BP, "Table 1", f"{BP_VIEW[view]}, {cov.replace('_', ' ')}", pv, our,
              f"MSE per DOF, paper's model units^2, 10 test frames, tracked points, sigma^2 = 0 "
              f"({ls} talker)", out_rec,
              "not measured" if our is None else factor_verdict(our, pv, 1.5, 10.0),
              RULE_1_5_10, False)
    # ratios and orderings (scale-free)
    ratios = [
        ("xy / yz, 10 modes (frontal against profile)", ("xy_all_points", "10_modes"),
         ("yz_all_points", "10_modes")),
        ("xy / yz, full covariance", ("xy_all_points", "full_covariance"),
         ("yz_all_points", "full_covariance")),
        ("xyz of 8 points / yz, 10 modes", ("xyz_8_points", "10_modes"),
         ("yz_all_points", "10_modes")),
        ("full covariance / 10 modes, xyz of 8 points", ("xyz_8_points", "full_covariance"),
         ("xyz_8_points", "10_modes")),
        ("full covariance / 10 modes, yz of all points", ("yz_all_points", "full_covariance"),
         ("yz_all_points", "10_modes")),
        ("full covariance / 10 modes, xy of all points", ("xy_all_points", "full_covariance"),
         ("xy_all_points", "10_modes")),
    ]
    for st, a, b in ratios:
        pv = BP_TABLE_1[a] / BP_TABLE_1[b]
        our = cells[a] / cells[b] if a in cells and b in cells and cells[b] > 0 else None
        if our is None:
            v = "not measured"
        else:
            v = factor_verdict(our, pv, 1.5, 1e9)
            if v == "same shape" and (our > 1) != (pv > 1):
                v = "differs"
        R.add(BP, "Table 1", f"ratio {st}", pv, our, "ratio of two Table 1 cells (scale-free)",
              out_rec, v, "reproduced: within 1.5x; same shape: on the same side of 1; differs: "
              "otherwise", False)
    for cov in ("10_modes", "full_covariance"):
        keys = [(v_, cov) for v_ in ("yz_all_points", "xyz_8_points", "xy_all_points")]
        paper_order = sorted(keys, key=lambda k_: BP_TABLE_1[k_])
        our = None
        if all(k_ in cells for k_ in keys):
            our = " < ".join(BP_VIEW[k_[0]].split(" ")[0] + ("8" if "8" in k_[0] else "")
                             for k_ in sorted(keys, key=lambda k_: cells[k_]))
        pv = " < ".join(BP_VIEW[k_[0]].split(" ")[0] + ("8" if "8" in k_[0] else "")
                        for k_ in paper_order)
        R.add(BP, "Table 1, Sec. 5", f"view ordering, {cov.replace('_', ' ')}", pv, our,
              "views sorted by their error (best first)", out_rec,
              "not measured" if our is None else "reproduced" if our == pv else "differs",
              RULE_EXACT, False)
    # mesh and DOF counts
    wanted = [("triangles", "faces of the mesh", 336, "Sec. 2.1"),
              ("nodes", "nodes of the mesh", 204, "Sec. 2.1"),
              ("dof", "degrees of freedom (three per node)", 612, "Sec. 2.1"),
              ("constrained_dof", "constrained DOF (16 lip points x 3)", 48, "Sec. 4.1"),
              ("free_dof", "free DOF (columns of P)", 600, "Sec. 4.1")]
    for q_, st, pv, where in wanted:
        our = None
        if counts is not None:
            sel = counts[counts["quantity"].astype(str) == q_]
            if len(sel):
                our = int(round(float(sel["our_value"].iloc[0])))
        R.add(BP, where, st, pv, our, f"count on the {ls} talker's mesh", out_cnt,
              "not measured" if our is None else "reproduced" if our == pv else "differs",
              RULE_EXACT, True)
    ds = None
    if counts is not None:
        sel = counts[counts["quantity"].astype(str) == "depth_share_test_frames"]
        if len(sel):
            ds = float(sel["our_value"].iloc[0])
    R.add(BP, "Sec. 5", "significant depth variation in the test frames",
          "significant", ds, "share of the depth (z) axis in the tracked points' displacement "
          "variance over the test frames", out_cnt,
          "not measured" if ds is None else "reproduced" if ds >= 1 / 3 else "differs",
          "reproduced: >= 1/3 (at least an average axis; the lip talker's calibration target); "
          "differs: otherwise", True)


# ---------------------------------------------------------------------------------------- all


def compare(inp: Inputs) -> pd.DataFrame:
    """The comparison table (``COLUMNS``), one row per statement."""
    R = _Rows(inp.paths or {})
    _table_i(R, inp)
    _table_i_text(R, inp)
    _sec3(R)
    _fig2(R, inp)
    _fig3(R, inp)
    _fig9(R, inp)
    _fig10(R, inp)
    _bp(R, inp)
    return pd.DataFrame(R.rows, columns=COLUMNS)


def read_inputs(paths: Mapping[str, str | None], tolerance_mm: float = 0.5,
                lip_subject: str = "virtual") -> Inputs:
    """Read the outputs named in ``paths`` (keys: 'selected', 'rank_summary', 'lip_reconstruction',
    'lip_counts', and 'r_values:LABEL', 'stability:LABEL', 'curve:LABEL', 'trajectory:LABEL',
    'coefficients:LABEL'); a missing key or file leaves that input empty."""
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
        paths={k: str(v) for k, v in paths.items() if v},
        tolerance_mm=tolerance_mm, lip_subject=lip_subject)


def summary_counts(table: pd.DataFrame) -> pd.DataFrame:
    """Verdict counts per paper and part (Table I cells vs the other rows), calibration apart."""
    t = table.copy()
    t["part"] = np.where(t["where"] == "Table I", "Table I cells", "other statements")
    g = t.groupby(["paper", "part", "calibration", "verdict"]).size().unstack(fill_value=0)
    for v in VERDICTS:
        if v not in g.columns:
            g[v] = 0
    return g[list(VERDICTS)].reset_index()


def to_markdown(table: pd.DataFrame) -> str:
    """Markdown: verdict counts, Table I as a grid (paper -> ours), then the other rows."""
    mark = {"reproduced": "✓", "same shape": "≈", "differs": "✗", "not measured": "–"}
    lines = ["Verdicts (✓ reproduced, ≈ same shape, ✗ differs, – not measured; "
             "calibration targets agree by construction):", "",
             "| paper | rows | calibration | reproduced | same shape | differs | not measured |",
             "|---|---|---|---|---|---|---|"]
    for _, r in summary_counts(table).iterrows():
        lines.append(f"| {r['paper']} | {r['part']} | {r['calibration']} | "
                     + " | ".join(str(int(r[v])) for v in VERDICTS) + " |")
    ti = table[table["where"] == "Table I"]
    if len(ti):
        labels = list(dict.fromkeys(s.split(",")[0] for s in ti["statement"]))
        lines += ["", "L&M Table I, paper → ours (✓ the same marker, ≈ a marker of the same "
                  "face region, ✗ another region):", "",
                  "| order | " + " | ".join(labels) + " |",
                  "|---|" + "---|" * len(labels)]
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
                cells.append(f"{p} → {o} {mark[r['verdict']]}")
            lines.append(f"| {i} | " + " | ".join(cells) + " |")
    rest = table[table["where"] != "Table I"]
    lines += ["", "| # | paper | where | statement | paper | ours | verdict | calibration |",
              "|---|---|---|---|---|---|---|---|"]
    for _, r in rest.iterrows():
        short = "L&M" if r["paper"] == LM else "B&P"
        lines.append(f"| {r['row']} | {short} | {r['where']} | {r['statement']} | "
                     f"{r['paper_value']} | {r['our_value']} | {mark[r['verdict']]} "
                     f"{r['verdict']} | {r['calibration']} |")
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
