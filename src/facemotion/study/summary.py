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


#: How to read the two columns beyond the papers (docs/results.md says more).
READING = [
    "  at noise: the epsilon-rank at the tolerance that white noise of the data's own estimated",
    "    level (mm per coordinate, in brackets) would reach; markers past it move no more than",
    "    measurement error.  k for N mm: the fewest main markers whose prediction of the rest",
    "    is within N mm on average on held-out sentences (bootstrap interval over them).",
]


def _k_cell(r) -> str:
    """k for the target with its interval, from one rank.tsv row ('-' without held-out
    sentences)."""
    if int(r.get("heldout_sentences", 0) or 0) == 0:
        return "- (no held-out)"
    k = r.get("k_for_target")
    if k is None or k != k:
        return "not reached"
    lo, hi = r.get("k_for_target_low"), r.get("k_for_target_high")
    if lo is None or lo != lo:
        return f"{int(k)} (no interval)"
    hi = "more" if hi is None or hi != hi else str(int(hi))
    return f"{int(k)} ({int(lo)}-{hi})"


def rank_lines(rank_summary, selected, n_pivots: int = 5) -> list[str]:
    """Per dataset: the epsilon-rank at every tolerance, at the data's noise level, k for the
    target held-out error with its interval, and the first pivots (Table I)."""
    from facemotion.ranking.result import ASKED
    from facemotion.regions.target import NOISE_LEVEL

    noise = rank_summary[rank_summary.get("tolerance_from", ASKED) == NOISE_LEVEL] \
        if "tolerance_from" in rank_summary else rank_summary.iloc[:0]
    if "tolerance_from" in rank_summary:  # not the paper's epsilon added for the comparison
        rank_summary = rank_summary[rank_summary["tolerance_from"] == ASKED]
    tols = sorted(rank_summary["tolerance_mm"].unique())
    head = "epsilon-rank at " + " / ".join(_fmt(t) for t in tols) + " mm"
    has_target = "k_for_target" in rank_summary
    target = (f"k for {_fmt(rank_summary['target_error_mm'].iloc[0])} mm "
              f"({rank_summary['interval_level'].iloc[0]:.0%})" if has_target else "")
    names = list(dict.fromkeys(rank_summary["dataset"]))
    width = max(len("dataset"), *(len(str(n)) for n in names))
    cols = [head, "at noise (mm)"] + ([target] if has_target else [])
    table = []
    for name in names:
        rows = rank_summary[rank_summary["dataset"] == name]
        r = rows.set_index("tolerance_mm")
        cells = [" / ".join(str(int(r.loc[t, "epsilon_rank"])) for t in tols)]
        nz = noise[noise["dataset"] == name]
        cells.append(f"{int(nz['epsilon_rank'].iloc[0])} of {int(nz['markers'].iloc[0])} "
                     f"({_fmt(nz['noise_mm'].iloc[0])})" if len(nz) else "-")
        if has_target:
            cells.append(_k_cell(rows.iloc[0].to_dict()))
        pivots = " ".join(str(m) for m in list(selected[name])[:n_pivots] if str(m))
        table.append((name, cells, pivots))
    widths = [max(len(h), *(len(c[i]) for _, c, _ in table)) for i, h in enumerate(cols)]

    def line(name, cells, last):
        return (f"  {name:<{width}}  "
                + "  ".join(f"{c:<{w}}" for c, w in zip(cells, widths, strict=True))
                + f"  {last}")

    out = [line("dataset", cols, f"first {n_pivots} pivots")]
    out += [line(name, cells, pivots) for name, cells, pivots in table]
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
        reading = ", ".join(sorted(set(rows["estimator_reading"].astype(str)))) \
            if "estimator_reading" in rows.columns else "not stated"
        out.append(f"  {subject}: view, then 10 modes / full covariance (paper's value); "
                   f"estimator reading {reading}")
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


def _names(names: list[str], limit: int = 4) -> str:
    """Sentence names, the middle ones elided when there are many."""
    if len(names) <= limit:
        return ", ".join(names)
    return f"{', '.join(names[:limit - 1])}, ..., {names[-1]}"


def take_lines(sentences: Mapping[str, object]) -> list[str]:
    """Per dataset: how many sentences trained and which, how many were held out and which
    (each dataset's data/sentences.tsv)."""
    out = []
    for name, t in sentences.items():
        roles = t["role"].astype(str)
        train = [str(x) for x in t.loc[roles == "train", "sentence"]]
        held = [str(x) for x in t.loc[roles == "heldout", "sentence"]]
        line = f"  {name}: trained on {len(train)} ({_names(train)})"
        line += (f"; held out {len(held)} ({_names(held)})" if held
                 else "; none held out (no held-out error)")
        out.append(line)
    return out


def comparison_lines(table) -> list[str]:
    """The papers' statements by class and verdict, predictions first (only they test the
    study)."""
    from facemotion.papers.table import CLASSES, VERDICTS

    out = ["The papers' statements by class, then verdict (tables/paper_comparison.tsv):"]
    for cls in CLASSES:
        rows = table[table["class"] == cls]
        if len(rows):
            counts = rows["verdict"].value_counts()
            out.append(f"  {cls:<16} {len(rows):>3}: " + ", ".join(
                f"{int(counts.get(v, 0))} {v}" for v in VERDICTS if counts.get(v, 0)))
    return out


def study_summary(study: str, root: str, rank_summary=None, selected=None,
                  lips: Mapping[str, object] | None = None, skipped: Sequence[str] = (),
                  dataset_sentences: Mapping[str, object] | None = None,
                  builtin_lips: Sequence[str] = (), comparison=None) -> str:
    """The closing summary: where the results are and the headline numbers.

    dataset_sentences: per dataset, its sentences table (which trained, which were held out).
    builtin_lips: lip subjects that are the built-in virtual lip talker in a study of the
    user's own sheet: not the user's data, so their Table 1 is left out with a pointer.
    comparison: the papers' comparison table (tables/paper_comparison.tsv)."""
    lines = [f"facemotion study '{study}': every output is under {root}/"]
    if dataset_sentences:
        lines += ["Sentences (<dataset>/data/sentences.tsv):", *take_lines(dataset_sentences)]
    if rank_summary is not None and selected is not None and len(rank_summary):
        lines += ["Lucero & Munhall 2008 (tables/rank_summary.tsv, tables/selected_markers.tsv):",
                  *rank_lines(rank_summary, selected), *READING]
    lips = dict(lips or {})
    for ls in builtin_lips:
        if lips.pop(ls, None) is not None:
            lines.append(f"Lip model: run on the built-in virtual lip talker '{ls}', not on "
                         f"your recordings; its table is lips/{ls}/reconstruction.tsv")
    lip = lip_lines(lips)
    if lip:
        lines += ["Basu & Pentland 1997 Table 1, MSE per degree of freedom in model units^2 "
                  "(lips/<subject>/reconstruction.tsv):", *lip]
    if comparison is not None and len(comparison):
        lines += comparison_lines(comparison)
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
