"""The comparison table's rows, classes, verdicts and rules, shared by both papers' modules.

Every row has a class, written before any number is measured:

* ``prediction``: the virtual talkers were not tuned on it; agreement is a finding.
* ``calibration``: the virtual talkers were tuned on it (``facemotion.virtual.talker.CALIBRATION``,
  the lip talker's depth share); agreement shows the tuning held, nothing more.
* ``by construction``: arithmetic, a theorem, or a consequence of the design or of a chosen
  reading; it checks the code, it cannot test the paper's claims.

Every rule is a ``Rule`` object: its ``text`` goes into the table, its ``verdict`` scores our
value, and its ``rejects`` are values it must score "differs" on (on both sides of the paper's
value where a number has two sides).  ``tests/papers/test_comparison.py`` runs every rule of a
real comparison on its ``rejects``, so a rule that cannot fail cannot be written.  A censored
value (a quantity that did not happen within the range measured, e.g. "not settled within 30
sentences") is ``math.inf`` and is never scored as agreement.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

COLUMNS = ["row", "paper", "where", "statement", "class", "paper_value", "our_value",
           "measure", "output", "verdict", "rule"]

CLASSES = ("prediction", "calibration", "by construction")

VERDICTS = ("reproduced", "same shape", "differs", "not measured")

LM = "Lucero & Munhall 2008"

BP = "Basu & Pentland 1997"


class Rule:
    """A verdict rule: ``text`` (what the table prints), ``verdict(ours)`` and ``rejects``."""

    text: str
    rejects: tuple

    def verdict(self, ours) -> str:  # pragma: no cover - every subclass defines it
        raise NotImplementedError


def _ratio(ours: float, paper: float) -> float:
    """max(ours / paper, paper / ours): how many times apart, both ways (inf if either <= 0)."""
    if ours <= 0 or paper <= 0:
        return math.inf
    return max(ours / paper, paper / ours)


@dataclass(frozen=True)
class Factor(Rule):
    """Within ``near`` times of the paper's value (either way): reproduced; within ``far``
    times: same shape (none when ``far`` is None); beyond: differs."""

    paper: float
    near: float
    far: float | None = None

    @property
    def text(self) -> str:
        shape = f"; same shape: within {self.far:g}x" if self.far else ""
        return (f"reproduced: within {self.near:g}x of the paper's value either way{shape}; "
                "differs: beyond")

    @property
    def rejects(self) -> tuple:
        f = (self.far or self.near) * 1.01
        return (self.paper * f, self.paper / f, 0.0, math.inf)

    def verdict(self, ours) -> str:
        f = _ratio(float(ours), self.paper)
        if f <= self.near:
            return "reproduced"
        return "same shape" if self.far and f <= self.far else "differs"


@dataclass(frozen=True)
class Band(Rule):
    """|ours - paper| <= ``tol``: reproduced; <= ``shape_tol``: same shape; else differs.
    ``unit`` names what the numbers count; ``precision`` says where the tolerance comes from."""

    paper: float
    tol: float
    shape_tol: float | None = None
    unit: str = ""
    precision: str = ""

    @property
    def text(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        why = f" ({self.precision})" if self.precision else ""
        shape = (f"; same shape: within {self.shape_tol:g}{u}" if self.shape_tol is not None
                 else "")
        return (f"reproduced: within {self.tol:g}{u} of {self.paper:g}{why}{shape}; "
                "differs: beyond (a censored value, not reached in the range measured, is "
                "beyond)")

    @property
    def rejects(self) -> tuple:
        d = (self.tol if self.shape_tol is None else self.shape_tol) + max(1.0, self.tol) * 0.5
        return (self.paper + d, self.paper - d, math.inf)

    def verdict(self, ours) -> str:
        d = abs(float(ours) - self.paper)
        if d <= self.tol:
            return "reproduced"
        return "same shape" if self.shape_tol is not None and d <= self.shape_tol else "differs"


@dataclass(frozen=True)
class Equal(Rule):
    """The same value (a count, a marker, an ordering): reproduced; otherwise differs."""

    paper: object
    other: object = None     # a wrong value the rule must reject (defaults below)

    @property
    def text(self) -> str:
        return "reproduced: equal to the paper's; differs: otherwise"

    @property
    def rejects(self) -> tuple:
        if self.other is not None:
            return (self.other,)
        if isinstance(self.paper, int | float):
            return (self.paper + 1, self.paper - 1)
        return (f"not {self.paper}",)

    def verdict(self, ours) -> str:
        return "reproduced" if ours == self.paper else "differs"


@dataclass(frozen=True)
class Check(Rule):
    """A rule over a structured value (pivot positions, a set of markers): ``score`` returns
    the verdict; ``rejects`` must be given, and each must score "differs"."""

    text: str
    score: Callable[[object], str]
    rejects: tuple = field(default=())

    def __post_init__(self):
        if not self.rejects:
            raise ValueError(f"rule {self.text!r}: give the values it must reject")

    def verdict(self, ours) -> str:
        return self.score(ours)


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
    """The table being built; ``rules`` keeps every row's rule object (for the tests)."""

    def __init__(self, paths: Mapping[str, str]):
        self.rows: list[dict] = []
        self.rules: list[Rule] = []
        self.paths = dict(paths or {})

    def add(self, paper: str, where: str, statement: str, cls: str, paper_value, our_value,
            measure: str, output: str, rule: Rule, scored=None) -> None:
        """One statement.  ``scored`` is the value the rule scores (default ``our_value``);
        None means not measured."""
        if cls not in CLASSES:
            raise ValueError(f"class {cls!r}")
        value = our_value if scored is None else scored
        verdict = "not measured" if value is None else rule.verdict(value)
        if verdict not in VERDICTS:
            raise ValueError(verdict)
        self.rules.append(rule)
        self.rows.append({
            "row": len(self.rows) + 1, "paper": paper, "where": where, "statement": statement,
            "class": cls, "paper_value": format_value(paper_value),
            "our_value": format_value(our_value), "measure": measure,
            "output": self.paths.get(output, output), "verdict": verdict, "rule": rule.text})


def get(mapping, key):
    return None if mapping is None else mapping.get(key)


def counts_by_class(table: pd.DataFrame, classes: Sequence[str] = CLASSES) -> pd.DataFrame:
    """Rows per class and verdict, predictions first (the results page and the summary)."""
    g = table.groupby(["class", "verdict"]).size().unstack(fill_value=0)
    for v in VERDICTS:
        if v not in g:
            g[v] = 0
    g = g.reindex([c for c in classes if c in g.index])
    return g[list(VERDICTS)].reset_index()
