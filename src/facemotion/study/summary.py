"""A study: its name, its own folder ``results/<study>/``, and the summary it closes with.

Each config is its own study, written under its own root with its own report and manifest, so
the default study (``paper``), the real recordings (``real``), the smoke study and the
virtual-talker sweep can be run in any order in one directory without overwriting each other.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from facemotion.errors import InputError

STUDY_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def study_name(setting: str | None, configfiles: Sequence[str | Path], sheet: str | Path,
               own_sheet: bool) -> str:
    """The study's name: the ``study`` setting, else the last ``--configfile``'s name, else the
    name of the user's own sheet (``--config subjects=SHEET``, or a host workflow's config),
    else ``paper``."""
    if setting:
        return setting
    if configfiles:
        source, name = "config file", Path(configfiles[-1]).stem
    elif own_sheet:
        source, name = "subject sheet", Path(sheet).stem
    else:
        return "paper"
    if not STUDY_NAME.match(name):
        raise InputError(f"setting study: not set, and the {source} name {name!r} cannot name "
                         "a study folder (letters, digits, '_', '.', '-'); set study")
    return name


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def rank_lines(rank_summary, selected, n_pivots: int = 5) -> list[str]:
    """Per dataset: the epsilon-rank at every tolerance and the first pivots (Table I)."""
    from facemotion.ranking.result import ASKED

    if "tolerance_from" in rank_summary:  # not the paper's epsilon added for the comparison
        rank_summary = rank_summary[rank_summary["tolerance_from"] == ASKED]
    tols = sorted(rank_summary["tolerance_mm"].unique())
    head = "epsilon-rank at " + " / ".join(_fmt(t) for t in tols) + " mm"
    names = list(dict.fromkeys(rank_summary["dataset"]))
    width = max(len("dataset"), *(len(str(n)) for n in names))
    out = [f"  {'dataset':<{width}}  {head}  first {n_pivots} pivots"]
    for name in names:
        r = rank_summary[rank_summary["dataset"] == name].set_index("tolerance_mm")
        ranks = " / ".join(str(int(r.loc[t, "epsilon_rank"])) for t in tols)
        pivots = " ".join(str(m) for m in list(selected[name])[:n_pivots] if str(m))
        out.append(f"  {name:<{width}}  {ranks:<{len(head)}}  {pivots}")
    for name in names:  # pivots mostly made up by gap filling, markers left out for it
        r = rank_summary[rank_summary["dataset"] == name]
        for col, what in (("mostly_filled_pivots", "mostly filled first pivots"),
                          ("left_out_filled", "left out as mostly filled")):
            text = str(r[col].iloc[0]) if col in r and len(r) else ""
            if text and text != "nan":
                out.append(f"  {name}: {what}: {text}")
    return out


def lip_lines(tables: Mapping[str, object]) -> list[str]:
    """Per lip subject and view: Basu & Pentland's Table 1 (MSE per degree of freedom, model
    units squared), ours beside the paper's, on the rows computed by the paper's definition."""
    out = []
    for subject, t in tables.items():
        rows = t[(t["paper_definition"].astype(str) == "True")]
        if rows.empty:
            continue
        out.append(f"  {subject}: view, then 10 modes / full covariance (paper's value)")
        for view in dict.fromkeys(rows["view"]):
            cells = []
            for cov in ("10_modes", "full_covariance"):
                r = rows[(rows["view"] == view) & (rows["covariance"] == cov)]
                if r.empty:
                    cells.append("-")
                    continue
                r = r.iloc[0]
                cells.append(f"{_fmt(r['mse_per_dof_model_units2'])} "
                             f"({_fmt(r['paper_mse_per_dof_model_units2'])})")
            out.append(f"    {view:<16} {cells[0]:<22} {cells[1]}")
    return out


def study_summary(study: str, root: str, rank_summary=None, selected=None,
                  lips: Mapping[str, object] | None = None, skipped: Sequence[str] = ()) -> str:
    """The closing summary: where the results are and the headline numbers."""
    lines = [f"facemotion study '{study}': every output is under {root}/"]
    if rank_summary is not None and selected is not None and len(rank_summary):
        lines += ["Lucero & Munhall 2008 (tables/rank_summary.tsv, tables/selected_markers.tsv):",
                  *rank_lines(rank_summary, selected)]
    lip = lip_lines(lips or {})
    if lip:
        lines += ["Basu & Pentland 1997 Table 1, MSE per degree of freedom in model units^2 "
                  "(lips/<subject>/reconstruction.tsv):", *lip]
    for s in skipped:
        lines.append(f"Skipped: {s}")
    lines += [f"Every output with its checksum: {root}/manifest.tsv"]
    return "\n".join(lines) + "\n"


def closing_message(root: str | Path, started: float, report_command: str) -> str | None:
    """What the terminal shows after a successful run: the summary this run wrote (None if it
    did not write one, e.g. a run of a single target) and how to build and open the report."""
    path = Path(root) / "summary.txt"
    if not path.is_file() or path.stat().st_mtime < started:
        return None
    report = f"{root}/report.html"
    return (f"\n{path.read_text()}The report (every figure and table, with captions):\n"
            f"  {report_command}\n  then open {report} in a web browser\n")
