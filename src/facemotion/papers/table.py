"""The comparison table's rows, columns, verdicts and rules, shared by both papers' modules."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

COLUMNS = ["row", "paper", "where", "statement", "paper_value", "our_value", "measure",
           "output", "verdict", "rule", "calibration"]


VERDICTS = ("reproduced", "same shape", "differs", "not measured")


LM = "Lucero & Munhall 2008"


BP = "Basu & Pentland 1997"


RULE_MARKER = ("reproduced: the same marker; same shape: a marker of the same face region "
               "(the virtual talker's regions, synth.REGIONS, applied to the paper's numbers); "
               "differs: otherwise")


RULE_1_5 = "reproduced: within 1.5x of the paper's value; same shape: within 3x; differs: beyond"


RULE_1_5_10 = ("reproduced: within 1.5x of the paper's value; same shape: within 10x (the same "
               "order of magnitude); differs: beyond")


RULE_EXACT = "reproduced: equal; differs: otherwise"


def factor_verdict(ours: float, paper: float, near: float, far: float) -> str:
    """reproduced within ``near``x, same shape within ``far``x, differs beyond."""
    if ours is None or not np.isfinite(ours):
        return "not measured"
    if ours <= 0 or paper <= 0:
        return "differs"
    f = max(ours / paper, paper / ours)
    return "reproduced" if f <= near else "same shape" if f <= far else "differs"


def format_value(v) -> str:
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
    lip_seeds: pd.DataFrame | None = None             # lips/table1_seeds.tsv
    paths: Mapping[str, str] | None = None            # what -> output path (for the table)
    lip_subject: str = "virtual"


class Rows:
    def __init__(self, paths: Mapping[str, str]):
        self.rows: list[dict] = []
        self.paths = dict(paths or {})

    def add(self, paper, where, statement, paper_value, our_value, measure, output, verdict,
            rule, calibration):
        if verdict not in VERDICTS:
            raise ValueError(verdict)
        self.rows.append({
            "row": len(self.rows) + 1, "paper": paper, "where": where, "statement": statement,
            "paper_value": format_value(paper_value), "our_value": format_value(our_value),
            "measure": measure,
            "output": self.paths.get(output, output), "verdict": verdict, "rule": rule,
            "calibration": "yes" if calibration else "no"})


def get(mapping, key):
    return None if mapping is None else mapping.get(key)
