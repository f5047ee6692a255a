"""The documentation's generated parts: every number, table and figure that README.md and
docs/*.md show, written from a study's outputs by one command.

    facemotion docs [--results results] [--repo .] [--check]      # make pages

A page holds hand-written prose and generated blocks::

    <!-- generated:NAME:start -->
    <!-- written by `make pages` (facemotion docs) from results/paper/...; ... -->
    ...
    <!-- generated:NAME:end -->

``BLOCKS`` lists every block this module writes, the page it is on, the studies whose outputs it
reads and how it renders them; ``FIGURES`` every figure the docs show, copied byte for byte from
a study's results into ``docs/figures/``. Only the text between a block's markers is rewritten,
so the prose around it stays as written; the prose never restates a generated number, so a
study that computes another number changes the page only here.

``--check`` writes nothing: it compares every block and figure with what would be written and
reports one line per difference (exit status 1), so a test can regenerate the docs from fresh
studies and fail on any number that moved. Blocks written by another command (the benchmarks'
tables in docs/performance.md) and blocks whose study has not been run are skipped, each with a
line saying why. Docs figures that no entry of ``FIGURES`` writes are reported, and deleted when
writing.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from facemotion.errors import InputError

COMMAND = "`make pages` (facemotion docs)"
BLOCK = re.compile(r"<!-- generated:(?P<name>[A-Za-z0-9_.-]+):start -->\n"
                   r"(?P<body>.*?)<!-- generated:(?P=name):end -->", re.S)
MARKER = re.compile(r"<!-- generated:(?P<name>[A-Za-z0-9_.-]+):(?P<end>start|end) -->")
#: Blocks another command writes: not checked here, only reported as skipped.
EXTERNAL = {
    "bench-qr": "make bench (benchmarks/bench_qr.py)",
    "bench-dense": "make bench (benchmarks/bench_dense.py)",
    "rule-times": "make bench (benchmarks/bench_study.py)",
    "restructure": "make bench (benchmarks/bench_before_after.py)",
    "bench-stream": "make bench (benchmarks/bench_stream.py)",
    "bench-stream-10g": "benchmarks/bench_stream.py --cases trc10g --block bench-stream-10g",
}
FIGURE_DIR = "docs/figures"
#: The studies the docs read, with the command that makes each.
STUDIES = {"paper": "make study", "real": "make real", "dense": "make dense"}


# ---- sources ---------------------------------------------------------------------------------

@dataclass
class Sources:
    """Where the generated parts come from: the repository (schema, configs), the folder that
    holds the studies' results (``<results>/<study>/``) and the shared real data."""

    repo: Path
    results: Path
    shared_data: Path | None = None

    def study(self, name: str) -> Path | None:
        """A finished study's root (it has its manifest, the last output), else None."""
        root = self.results / name
        return root if (root / "manifest.tsv").is_file() else None

    def root(self, name: str) -> Path:
        root = self.study(name)
        if root is None:
            raise InputError(f"{self.results / name}: no finished study {name!r} there "
                             f"(run {STUDIES.get(name, 'it')})")
        return root


def _tsv(path: Path) -> pd.DataFrame:
    if not path.is_file():
        raise InputError(f"{path}: not found (the docs read it; did the study change?)")
    return pd.read_csv(path, sep="\t", dtype=str, keep_default_na=False)


def _datasets(root: Path) -> dict[str, str]:
    """Label -> folder of every dataset of a study, in the study's order (rank_summary.tsv)."""
    labels = list(dict.fromkeys(_tsv(root / "tables" / "rank_summary.tsv")["dataset"]))
    folders = {}
    for meta in sorted(root.glob("*/qr/rank.meta.json")):
        params = json.loads(meta.read_text())["config"]["params"]
        folders[str(params.get("label") or meta.parents[1].name)] = meta.parents[1].name
    missing = [lab for lab in labels if lab not in folders]
    if missing:
        raise InputError(f"{root}: no dataset folder for {', '.join(missing)}")
    return {lab: folders[lab] for lab in labels}


# ---- formatting ------------------------------------------------------------------------------

def _table(header: Sequence[str], rows: Sequence[Sequence[object]],
           align: str | None = None) -> str:
    """A markdown table; ``align`` one letter per column (l or r)."""
    align = align or "l" * len(header)
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(rule) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _num(x, digits: int = 3) -> str:
    """A number to ``digits`` significant digits, without exponent where that is short."""
    x = float(x)
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    if 1e-3 <= abs(x) < 1e5:
        dec = max(0, digits - 1 - math.floor(math.log10(abs(x))))
        return f"{x:.{dec}f}"
    return f"{x:.{digits - 1}e}"


def _pct(x, digits: int = 1) -> str:
    return f"{100 * float(x):.{digits}f} %"


def _range(values, fmt: Callable[[float], str]) -> str:
    lo, hi = fmt(min(values)), fmt(max(values))
    if lo == hi:
        return lo
    unit = ""
    for u in (" %", " mm"):
        if lo.endswith(u) and hi.endswith(u):
            lo, hi, unit = lo[:-len(u)], hi[:-len(u)], u
    return f"{lo} to {hi}{unit}" if "e" in lo + hi else f"{lo}-{hi}{unit}"


def _short(x) -> str:
    """A count or a setting as written: 336, 99.21, 0.01."""
    return f"{float(x):.4g}"


def _pivots(r_values: pd.DataFrame, n: int = 5) -> str:
    return " ".join(r_values["marker"].tolist()[:n])


# ---- the blocks ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Block:
    """One generated block: its page, its name, the studies it reads, what it is written from
    (for its header line) and how it is rendered."""

    page: str
    name: str
    studies: tuple[str, ...]
    source: str
    render: Callable[[Sources], str]
    needs_shared_data: bool = False


@dataclass(frozen=True)
class Figure:
    """A figure the docs show: ``docs/figures/<name>``, a copy of ``results/<study>/<path>``."""

    name: str
    study: str
    path: str


BLOCKS: list[Block] = []


def block(page: str, name: str, studies: Sequence[str], source: str,
          needs_shared_data: bool = False):
    """Register a block renderer (a decorator)."""
    def register(fn: Callable[[Sources], str]) -> Callable[[Sources], str]:
        BLOCKS.append(Block(page, name, tuple(studies), source, fn, needs_shared_data))
        return fn
    return register


def _asked(rank: pd.DataFrame) -> pd.DataFrame:
    """The rows of rank.tsv at the tolerances the setting asked for (not the paper's epsilon
    or the noise level, added beside them)."""
    from facemotion.ranking.result import ASKED

    return rank[rank["tolerance_from"] == ASKED] if "tolerance_from" in rank else rank


def _eps_ranks(rank: pd.DataFrame) -> str:
    return " / ".join(_asked(rank)["epsilon_rank"].tolist())


def _tolerances(rank: pd.DataFrame) -> str:
    return " / ".join(f"{float(t):g}" for t in _asked(rank)["tolerance_mm"])


def _headline(src: Sources, study: str) -> str:
    """Per dataset, beyond the papers: the noise level, the epsilon-rank there, and k for the
    target held-out error with its interval (rank.tsv)."""
    from facemotion.regions.target import NOISE_LEVEL

    rows, target, level = [], "", ""
    for label, _, rank, _ in _study_datasets(src, study):
        noise = rank[rank["tolerance_from"] == NOISE_LEVEL]
        first = rank.iloc[0]
        target = f"{float(first['target_error_mm']):g}"
        level = f"{float(first['interval_level']):.0%}"
        k = first["k_for_target"]
        if int(first["heldout_sentences"]) == 0:
            kcell = "— (no held-out sentences)"
        elif not k:
            kcell = "not reached"
        elif not first["k_for_target_low"]:
            kcell = f"{k} (no interval: {first['heldout_sentences']} held-out sentence(s))"
        else:
            hi = first["k_for_target_high"] or "more"
            kcell = f"{k} ({first['k_for_target_low']}-{hi})"
        rows.append([label, first["markers"],
                     f"{_num(float(first['noise_mm']))} ({first['noise_source']})",
                     noise["epsilon_rank"].iloc[0] if len(noise) else "—", kcell,
                     first["heldout_sentences"]])
    return _table(["dataset", "markers", "noise, mm per coordinate (estimate)",
                   "epsilon-rank at the noise", f"k for {target} mm ({level} interval)",
                   "held-out sentences"], rows, "lrllll")


def _study_datasets(src: Sources, study: str):
    """(label, folder, rank.tsv, r_values.tsv) of every dataset of a study."""
    root = src.root(study)
    for label, folder in _datasets(root).items():
        yield (label, root / folder, _tsv(root / folder / "qr" / "rank.tsv"),
               _tsv(root / folder / "qr" / "r_values.tsv"))


def _curve_at(root: Path, ks: Sequence[int]) -> dict[int, pd.Series] | None:
    path = root / "eval" / "error_curve.tsv"
    if not path.is_file():
        return None
    curve = _tsv(path)
    return {int(r["k"]): r for _, r in curve.iterrows() if int(r["k"]) in ks}


def _paper_eps(rank: pd.DataFrame) -> pd.Series:
    from facemotion.papers.lucero_munhall import EPSILON_MM

    sel = rank[rank["tolerance_mm"].astype(float) == EPSILON_MM]
    return sel.iloc[0]


# README ---------------------------------------------------------------------------------------

@block("README.md", "readme-summary", ["paper"],
       "results/paper/tables/rank_summary.tsv, <dataset>/qr/r_values.tsv, "
       "<dataset>/eval/error_curve.tsv, tables/paper_comparison.tsv")
def _readme_summary(src: Sources) -> str:
    from facemotion.papers.comparison import summary_counts
    from facemotion.papers.lucero_munhall import EPSILON_MM
    from facemotion.papers.table import VERDICTS

    rows, head = [], "k for the target"
    for label, folder, rank, r_values in _study_datasets(src, "paper"):
        curve = _curve_at(folder, [1, 10])
        err = "—" if not curve or 10 not in curve else (
            f"{_num(curve[10]['mean_abs_error_mm'])} mm")
        first = rank.iloc[0]
        head = (f"k for {float(first['target_error_mm']):g} mm "
                f"({float(first['interval_level']):.0%} interval)")
        lo, hi = first["k_for_target_low"], first["k_for_target_high"] or "more"
        kt = (f"{first['k_for_target']} ({lo}-{hi})" if lo else first["k_for_target"] or "—")
        rows.append([label, _paper_eps(rank)["epsilon_rank"], _pivots(r_values), err, kt])
    out = [_table(["dataset", f"epsilon-rank (ε = {EPSILON_MM:g} mm)", "first 5 pivots",
                   "held-out error, k = 10", head], rows, "lrlll")]
    table = _tsv(src.root("paper") / "tables" / "paper_comparison.tsv")
    counts = summary_counts(table)
    crow = [[r["paper"], r["class"], r["part"]] + [str(int(r[v])) for v in VERDICTS]
            for _, r in counts.iterrows()]
    out += ["", "The papers' quantitative statements by class (predictions first: only they "
            "test the study) and verdict:", "",
            _table(["paper", "class", "statements", *VERDICTS], crow, "lllrrrr")]
    return "\n".join(out)


# docs/lucero-munhall.md -----------------------------------------------------------------------

LM_PAGE = "docs/lucero-munhall.md"


@block(LM_PAGE, "lm-table-i", ["paper"], "results/paper/tables/selected_markers.tsv")
def _lm_table_i(src: Sources) -> str:
    sel = _tsv(src.root("paper") / "tables" / "selected_markers.tsv")
    return _table(list(sel.columns), sel.values.tolist(), "r" + "r" * (sel.shape[1] - 1))


@block(LM_PAGE, "lm-epsilon-rank", ["paper"],
       "results/paper/<dataset>/qr/rank.tsv")
def _lm_epsilon_rank(src: Sources) -> str:
    rows = []
    tol = ""
    for label, _, rank, _ in _study_datasets(src, "paper"):
        tol = _tolerances(rank)
        at = _paper_eps(rank)
        rows.append([label, f"{int(at['rows']):,} x {at['markers']}", at["route"],
                     _eps_ranks(rank), " / ".join(_asked(rank)["diagonal_count"]),
                     _num(at["r22_norm_at_rank_mm"]), at["redundant_markers"] or "—"])
    return _table(["dataset", "A (rows x markers)", "route", f"epsilon-rank at {tol} mm",
                   "diagonal count", "‖R22‖₂ at the rank, ε = 0.5 mm (mm)",
                   "markers after the rank"], rows, "lllllrl")


@block(LM_PAGE, "lm-gaps", ["paper"],
       "results/paper/<dataset>/data/gap_report.tsv and qr/redundancy.tsv")
def _lm_gaps(src: Sources) -> str:
    rows, copies = [], []
    for label, folder, _, _ in _study_datasets(src, "paper"):
        gaps = _tsv(folder / "data" / "gap_report.tsv")
        filled = gaps[gaps["filled_frames"].astype(int) > 0]
        by_method = filled.groupby("fill_method")["filled_frames"].apply(
            lambda s: s.astype(int).sum())
        rows.append([label, f"{int(gaps['frames'].iloc[0]):,}",
                     f"{gaps['missing_frames'].astype(int).sum():,}",
                     f"{gaps['outlier_frames'].astype(int).sum():,}",
                     ", ".join(f"{m}: {n:,}" for m, n in by_method.items()) or "—"])
        red = _tsv(folder / "qr" / "redundancy.tsv")
        for _, r in red.iterrows():
            copies.append([label, r["marker"], r["explained_by"], _num(r["coefficient"]),
                           _num(r["residual_rms_mm"]), f"{int(r['n_frames']):,}"])
    out = [_table(["dataset", "frames", "missing samples", "outlier samples",
                   "filled samples by method"], rows, "lrrrl"), ""]
    if copies:
        out.append(_table(["dataset", "marker", "explained by", "coefficient",
                           "residual RMS (mm)", "frames"], copies, "lllrrr"))
    else:
        out.append("No marker copies another in any dataset.")
    return "\n".join(out)


@block(LM_PAGE, "lm-error-curve", ["paper"], "results/paper/<dataset>/eval/error_curve.tsv")
def _lm_error_curve(src: Sources) -> str:
    ks = [1, 5, 10, 20, 30]
    rows = []
    for label, folder, _, _ in _study_datasets(src, "paper"):
        curve = _curve_at(folder, ks)
        if curve is None:
            continue
        cells = [f"{_num(curve[k]['mean_abs_error_mm'])} / "
                 f"{_pct(curve[k]['rel_error_per_marker'], 0)}" if k in curve else "—"
                 for k in ks]
        ratio = (float(curve[10]["mean_abs_error_mm"]) / float(curve[1]["mean_abs_error_mm"])
                 if 1 in curve and 10 in curve else float("nan"))
        rows.append([label, *cells, _num(ratio, 2)])
    return _table(["dataset", *[f"k = {k}" for k in ks], "k = 10 / k = 1"], rows,
                  "l" + "r" * (len(ks) + 1))


@block(LM_PAGE, "lm-fig9", ["paper"], "results/paper/S1/eval/trajectory_errors.tsv")
def _lm_fig9(src: Sources) -> str:
    from facemotion.papers.lucero_munhall import FIG9_MAX_MM

    folder = src.root("paper") / _datasets(src.root("paper"))["S1"]
    tr = _tsv(folder / "eval" / "trajectory_errors.tsv")
    first = tr.iloc[0]
    role = "main" if first["in_basis"].lower() == "true" else "secondary"
    rows = [[axis, _num(FIG9_MAX_MM.get(axis, float("nan")), 2), _num(r["max_abs_error_mm"])]
            for axis, r in zip(tr["axis"], (r for _, r in tr.iterrows()), strict=True)]
    return (f"Marker {first['marker']} is a {role} marker of S1's basis of k = {first['k']}; "
            f"its largest errors in held-out sentence {first['sentence']}:\n\n"
            + _table(["axis", "paper (mm)", "ours (mm)"], rows, "lrr"))


@block(LM_PAGE, "lm-optimality", ["paper"], "results/paper/<dataset>/qr/optimality.tsv")
def _lm_optimality(src: Sources) -> str:
    rows, qr_all, greedy_all = [], [], []
    ks: list[str] = []
    for label, folder, _, _ in _study_datasets(src, "paper"):
        opt = _tsv(folder / "qr" / "optimality.tsv")
        ks = opt["k"].tolist()
        qr = opt["qr_over_optimal"].astype(float) - 1
        greedy = (opt["greedy_residual_rms_mm"].astype(float)
                  / opt["optimal_residual_rms_mm"].astype(float) - 1)
        qr_all += qr.tolist()
        greedy_all += greedy.tolist()
        rows.append([label] + [f"{_pct(q)} / {_pct(g)}" for q, g in zip(qr, greedy,
                                                                       strict=True)])
    out = _table(["dataset", *[f"k = {k}" for k in ks]], rows, "l" + "r" * len(ks))
    return (out + "\n\nOver all datasets and k: pivoted QR "
            f"{_range(qr_all, _pct)}, greedy forward selection {_range(greedy_all, _pct)} "
            "above the optimum.")


@block(LM_PAGE, "lm-headline", ["paper"], "results/paper/<dataset>/qr/rank.tsv")
def _lm_headline(src: Sources) -> str:
    return _headline(src, "paper")


@block(LM_PAGE, "lm-stability", ["paper"],
       "results/paper/<dataset>/qr/stability.tsv and qr/stability_agreement.tsv")
def _lm_stability(src: Sources) -> str:
    rows = []
    agree_cols: list[tuple[str, str]] = []
    for label, folder, _, _ in _study_datasets(src, "paper"):
        stab = _tsv(folder / "qr" / "stability.tsv")
        agree = _tsv(folder / "qr" / "stability_agreement.tsv")
        n = len(stab)
        ns = sorted({int(x) for x in agree["n_sentences"]})
        picks = [x for x in (10, 20) if x in ns]
        agree_cols = [(k, str(m)) for k in sorted(set(agree["k"]), key=int) for m in picks]
        cells = []
        for k, m in agree_cols:
            sel = agree[(agree["k"] == k) & (agree["n_sentences"] == m)]
            cells.append(_pct(sel["agreement_fraction"].iloc[0], 0) if len(sel) else "—")
        settled = stab["settled"].str.lower() == "true" if "settled" in stab else None
        worst = (f"not within {int(agree['n_sentences'].astype(int).max())}"
                 if settled is not None and not settled.all()
                 else str(max(int(x) for x in stab["settled_sentences"])))
        rows.append([label, str(n), worst,
                     str(max(int(float(x)) for x in stab["settled_median"])), *cells,
                     agree["n_replicates"].iloc[0]])
    header = ["dataset", "pivots followed", "settled after (given order)",
              "settled after (median over orders, worst pivot)",
              *[f"first {k} agree, {m} sentences" for k, m in agree_cols], "random orders"]
    return _table(header, rows, "l" + "r" * (len(header) - 1))


@block(LM_PAGE, "lm-comparison", ["paper"], "results/paper/tables/paper_comparison.tsv "
       "(facemotion.papers.comparison.to_markdown, Lucero & Munhall's rows)")
def _lm_comparison(src: Sources) -> str:
    from facemotion.papers.table import LM

    return _comparison_rows(src, LM)


def _comparison_rows(src: Sources, paper: str) -> str:
    """One paper's rows of the default study's comparison table, as markdown."""
    from facemotion.papers.comparison import to_markdown

    table = _tsv(src.root("paper") / "tables" / "paper_comparison.tsv")
    return to_markdown(table[table["paper"] == paper]).rstrip("\n")


# docs/basu-pentland.md ------------------------------------------------------------------------

BP_PAGE = "docs/basu-pentland.md"


def _lip_subjects(src: Sources) -> list[str]:
    root = src.root("paper") / "lips"
    names = [p.parent.name for p in sorted(root.glob("*/reconstruction.tsv"))]
    # the virtual lip talker first: it is the one the paper comparison reads
    return sorted(names, key=lambda n: (n != "virtual", n))


@block(BP_PAGE, "bp-counts", ["paper"], "results/paper/lips/<lip subject>/model_counts.tsv")
def _bp_counts(src: Sources) -> str:
    subjects = _lip_subjects(src)
    tables = {s: _tsv(src.root("paper") / "lips" / s / "model_counts.tsv") for s in subjects}
    quantities = list(dict.fromkeys(q for t in tables.values() for q in t["quantity"]))
    rows = []
    for q in quantities:
        first = next(t[t["quantity"] == q].iloc[0] for t in tables.values()
                     if (t["quantity"] == q).any())
        cells = []
        for s in subjects:
            sel = tables[s][tables[s]["quantity"] == q]
            cells.append(_short(sel["our_value"].iloc[0]) if len(sel) else "—")
        paper = _short(first["paper_value"]) if first["paper_value"] else "—"
        rows.append([q.replace("_", " "), first["unit"], first["paper_place"] or "—", paper,
                     *cells])
    return _table(["quantity", "unit", "paper's place", "paper", *subjects], rows,
                  "llll" + "r" * len(subjects))


def _reconstruction(src: Sources, subject: str) -> pd.DataFrame:
    return _tsv(src.root("paper") / "lips" / subject / "reconstruction.tsv")


VIEWS = ("xyz_8_points", "yz_all_points", "xy_all_points")
COVARIANCES = ("10_modes", "full_covariance")


def _cell(rec: pd.DataFrame, view: str, cov: str, column: str, reading: str = "noise_term",
          point_set: str = "tracked_points") -> str:
    sel = rec[(rec["view"] == view) & (rec["covariance"] == cov)
              & (rec["estimator_reading"] == reading) & (rec["point_set"] == point_set)]
    return _num(sel[column].iloc[0]) if len(sel) else "—"


@block(BP_PAGE, "bp-table-1", ["paper"],
       "results/paper/lips/<lip subject>/reconstruction.tsv (rows with paper_definition)")
def _bp_table_1(src: Sources) -> str:
    from facemotion.papers.basu_pentland import BP_TABLE_1, BP_VIEW

    subjects = _lip_subjects(src)
    recs = {s: _reconstruction(src, s) for s in subjects}
    rows = []
    for view in VIEWS:
        row = [BP_VIEW[view]] + [_num(BP_TABLE_1[(view, c)]) for c in COVARIANCES]
        for s in subjects:
            row += [_cell(recs[s], view, c, "mse_per_dof_model_units2") for c in COVARIANCES]
        rows.append(row)
    header = ["view", "paper: 10 modes", "paper: full cov."]
    for s in subjects:
        header += [f"{s}: 10 modes", f"{s}: full cov."]
    return _table(header, rows, "l" + "r" * (len(header) - 1))


@block(BP_PAGE, "bp-table-1-more", ["paper"],
       "results/paper/lips/<lip subject>/reconstruction.tsv")
def _bp_table_1_more(src: Sources) -> str:
    from facemotion.papers.basu_pentland import BP_VIEW

    rows = []
    for s in _lip_subjects(src):
        rec = _reconstruction(src, s)
        for view in VIEWS:
            rows.append([s, BP_VIEW[view]]
                        + [_cell(rec, view, c, "mse_per_dof_mm2") for c in COVARIANCES]
                        + [_cell(rec, view, c, "mse_per_dof_model_units2", "pseudo_inverse")
                           for c in COVARIANCES])
    return _table(["lip subject", "view", "mm², 10 modes", "mm², full cov.",
                   "pseudo-inverse (σ² = 0), 10 modes", "pseudo-inverse (σ² = 0), full cov."],
                  rows, "llrrrr")


@block(BP_PAGE, "bp-table-1-seeds", ["paper"], "results/paper/lips/table1_seeds.tsv")
def _bp_table_1_seeds(src: Sources) -> str:
    from facemotion.papers.basu_pentland import BP_TABLE_1, READING_NAMES

    t = _tsv(src.root("paper") / "lips" / "table1_seeds.tsv")
    ratios = {v: BP_TABLE_1[(v, "full_covariance")] / BP_TABLE_1[(v, "10_modes")]
              for v in VIEWS}
    rows = [["paper (Table 1)", "—", "—"] + [_num(ratios[v]) for v in VIEWS]
            + ["yes" if ratios["xy_all_points"] > 1 else "no"]]
    for (ls, seed, reading), g in t.groupby(["lip_subject", "seed", "estimator_reading"],
                                            sort=False):
        cell = g.set_index("view")
        name = READING_NAMES.get(reading, reading)
        if cell["chosen_reading"].iloc[0] == "True":
            name += " (chosen)"
        rows.append([ls, seed, name] + [_num(cell.loc[v, "full_over_modes"]) for v in VIEWS]
                    + ["yes" if cell.loc["xy_all_points", "modes_better"] == "True" else "no"])
    return _table(["lip subject", "seed", "estimator reading", "xyz of 8 points",
                   "yz of all points", "xy of all points", "frontal: 10 modes better"],
                  rows, "lrlrrrl")


@block(BP_PAGE, "bp-heldout-points", ["paper"],
       "results/paper/lips/<lip subject>/heldout_points.tsv")
def _bp_heldout(src: Sources) -> str:
    rows = []
    for s in _lip_subjects(src):
        t = _tsv(src.root("paper") / "lips" / s / "heldout_points.tsv")
        if "landmark" not in t.columns:
            continue
        fit = t[t["view"] == "minimal_force_fit"]
        if not len(fit):
            continue
        err = fit["rms_error_mm"].astype(float)
        disp = fit["rms_displacement_mm"].astype(float)
        rows.append([s, str(len(fit)), _num(math.sqrt((err ** 2).mean())),
                     _num(math.sqrt((disp ** 2).mean()))])
    if not rows:
        return "No lip subject has held-out landmarks."
    return _table(["lip subject", "held-out landmarks", "RMS error of the fit (mm)",
                   "RMS displacement (mm)"], rows, "lrrr")


@block(BP_PAGE, "bp-comparison", ["paper"], "results/paper/tables/paper_comparison.tsv "
       "(facemotion.papers.comparison.to_markdown, Basu & Pentland's rows)")
def _bp_comparison(src: Sources) -> str:
    from facemotion.papers.table import BP

    return _comparison_rows(src, BP)


# docs/methods.md ------------------------------------------------------------------------------

METHODS_PAGE = "docs/methods.md"


@block(METHODS_PAGE, "r-normalisation", [],
       "facemotion.ranking.result.implied_rms_per_coordinate on the paper's quoted values")
def _r_normalisation(src: Sources) -> str:
    from facemotion.ranking.result import R_NORMALISATIONS, implied_rms_per_coordinate

    # L&M Sec. II: 30 sentences of 2-3 s at 120 Hz: 3M = 3 x frames rows
    rows_lo, rows_hi = 3 * 30 * 2 * 120, 3 * 30 * 3 * 120
    divisor = {"none": "1", "per_coordinate": "sqrt(3M)", "per_frame": "sqrt(M)"}
    rows = []
    for norm in R_NORMALISATIONS:
        cells = []
        for r in (22.70, 0.10):
            lo = implied_rms_per_coordinate(r, rows_lo, norm)
            hi = implied_rms_per_coordinate(r, rows_hi, norm)
            cells.append(_range([lo, hi], _num) + " mm")
        rows.append([f"`{norm}`", divisor.get(norm, "?"), *cells])
    return (f"With 3M = {rows_lo:,}-{rows_hi:,} rows (30 sentences of 2-3 s at 120 Hz):\n\n"
            + _table(["`qr.r_normalisation`", "R divided by",
                      "r56 = 22.70 mm implies, RMS per coordinate",
                      "r57 = 0.10 mm implies"], rows, "llrr"))


@block(METHODS_PAGE, "calibration", [], "facemotion.virtual.talker.CALIBRATION and "
       "facemotion.lips.virtual.DEPTH_SHARE_TARGET")
def _calibration(src: Sources) -> str:
    from fractions import Fraction

    from facemotion.lips.virtual import DEPTH_SHARE_TARGET
    from facemotion.virtual.talker import CALIBRATION

    lines = [f"{i}. {fact}" for i, fact in enumerate(CALIBRATION, 1)]
    lines += ["", "The virtual lip talker (Basu & Pentland) is calibrated on one fact: over the "
              "test frames the depth (z) axis carries at least "
              f"{Fraction(DEPTH_SHARE_TARGET).limit_denominator(20)} of the tracked points' "
              "displacement variance (Sec. 5, "
              "\"a significant amount of depth variation in the test frames\")."]
    return "\n".join(lines)


@block(METHODS_PAGE, "calibration-rows", ["paper"], "results/paper/tables/paper_comparison.tsv "
       "(rows of class calibration)")
def _calibration_rows(src: Sources) -> str:
    table = _tsv(src.root("paper") / "tables" / "paper_comparison.tsv")
    cal = table[table["class"] == "calibration"]
    rows = [[r["row"], "L&M" if r["paper"].startswith("Lucero") else "B&P", r["where"],
             r["statement"], r["paper_value"], r["our_value"], r["verdict"]]
            for _, r in cal.iterrows()]
    n_pred = int((table["class"] == "prediction").sum())
    n_cons = int((table["class"] == "by construction").sum())
    return (_table(["#", "paper", "where", "statement", "paper", "ours", "verdict"], rows)
            + f"\n\nOf the other rows of the comparison table, {n_pred} are predictions and "
            f"{n_cons} follow by construction (arithmetic, a theorem, or the design).")


# docs/your-data.md ----------------------------------------------------------------------------

DATA_PAGE = "docs/your-data.md"


def _esc(text: str) -> str:
    """Text for a table cell: no pipes, no line breaks, and <name> shown, not read as HTML."""
    return (str(text).replace("|", "\\|").replace("\n", " ").replace("<", "&lt;")
            .replace(">", "&gt;"))


@block(DATA_PAGE, "sheet-columns", [], "workflow/schemas/subjects.schema.yaml "
       "(facemotion.study.settings.sheet_schema)")
def _sheet_columns(src: Sources) -> str:
    from facemotion.study.settings import sheet_schema

    schema = sheet_schema(src.repo / "workflow" / "schemas" / "subjects.schema.yaml")
    required = set(schema.get("required", []))
    rows = []
    for name, spec in schema["properties"].items():
        allowed = spec.get("enum")
        what = spec.get("description", "")
        if allowed:
            values = ", ".join(f"`{v}`" for v in allowed if v != "")
            what = (what + " " if what else "") + f"Values: {values}."
        if spec.get("pattern") == "^[0-9]*$":
            what = (what + " " if what else "") + "A whole number, or empty."
        rows.append([f"`{name}`", "yes" if name in required else "no", _esc(what) or "—"])
    return _table(["column", "required", "what it holds"], rows)


@block(DATA_PAGE, "formats", [], "facemotion.io.registry.FORMATS")
def _formats(src: Sources) -> str:
    from facemotion.io.base import UNITS
    from facemotion.io.registry import FORMATS

    rows = [[f"`{f.name}`", _esc(f.title), ", ".join(f"`{s}`" for s in f.suffixes) or "—",
             _esc(f.units), "yes" if f.writer else "no"] for f in FORMATS.values()]
    return (_table(["format", "what", "told by the suffix", "units", "the study writes it"],
                   rows)
            + "\n\nUnits a sheet may give: " + ", ".join(f"`{u}`" for u in UNITS) + ".")


@block(DATA_PAGE, "designs", [], "facemotion.virtual.designs.DESIGNS")
def _designs(src: Sources) -> str:
    from facemotion.virtual.designs import DESIGNS

    rows = []
    for d in DESIGNS.values():
        rows.append([f"`{d.name}`", _esc(d.description),
                     str(d.sentences) if d.sentences else "the sheet's `n_sentences`",
                     str(d.vertices) if d.vertices else "57 + 6 head band",
                     ", ".join(f"`{f}`" for f in d.format_names),
                     ", ".join(f"{t}={s}" for t, s in d.copy_markers) or "—"])
    return _table(["design", "what", "sentences", "points", "formats", "copy_markers"], rows)


def _schema(src: Sources) -> dict:
    import yaml

    with open(src.repo / "workflow" / "schemas" / "config.schema.yaml") as fh:
        return yaml.safe_load(fh)


@block(DATA_PAGE, "validation-margins", ["paper", "real"],
       "facemotion.ingest.validation.margins on the shared data and results/paper/virtual; "
       "shape differences from results/{real,paper}/<dataset>/data/sentences.tsv; limits: "
       "workflow/schemas/config.schema.yaml", needs_shared_data=True)
def _validation_margins(src: Sources) -> str:
    from facemotion.ingest.validation import margins
    from facemotion.io.registry import read_recording

    assert src.shared_data is not None

    def shapes(study: str, prefix: str) -> list[float]:
        root = src.root(study)
        return [float(x) for folder in _datasets(root).values() if folder.startswith(prefix)
                for x in _tsv(root / folder / "data" / "sentences.tsv")["shape_rms_mm"]]

    groups = [("AnimFace (shared data, C3D)",
               sorted((src.shared_data / "animface").glob("*.c3d")), shapes("real", "animface")),
              ("GRID (shared data, TRC)", sorted((src.shared_data / "grid").glob("*.trc")),
               shapes("real", "grid")),
              ("virtual S1, S2a, S2b (results/paper/virtual)",
               sorted(src.root("paper").glob("virtual/S*/*.c3d")), shapes("paper", ""))]
    rows, speeds, dists, spreads, shape_all = [], [], [], [], []
    for name, files, shape in groups:
        if not files:
            raise InputError(f"no files for {name}")
        ms = [margins(read_recording(f)) for f in files]
        rates = sorted({m["rate_hz"] for m in ms})
        sp = [m["max_speed_mm_s"] for m in ms]
        di = [m["max_distance_mm"] for m in ms]
        sr = [m["spread_mm"] for m in ms]
        speeds += sp
        dists += di
        spreads += sr
        shape_all += shape
        rows.append([name, str(len(files)), ", ".join(f"{r:g}" for r in rates),
                     f"{max(sp):.0f}", f"{max(di):.0f}",
                     _range(sr, lambda x: f"{x:.0f}"), f"{max(shape):.1f}"])
    props = _schema(src)["properties"]
    gaps, checks = props["gaps"]["properties"], props["checks"]["properties"]
    speed_lim = gaps["max_speed_mm_s"]["default"]
    dist_lim = gaps["max_distance_mm"]["default"]
    lo, hi = checks["face_spread_mm"]["default"]
    shape_lim = checks["max_shape_rms_mm"]["default"]
    rows.append(["**default limit**", "", "", f"{speed_lim:g} (`gaps.max_speed_mm_s`)",
                 f"{dist_lim:g} (`gaps.max_distance_mm`)",
                 f"{lo:g}-{hi:g} (`checks.face_spread_mm`)",
                 f"{shape_lim:g} (`checks.max_shape_rms_mm`)"])
    rows.append(["**limit / largest measured**", "", "", f"{speed_lim / max(speeds):.1f}x",
                 f"{dist_lim / max(dists):.1f}x",
                 f"{min(spreads) / lo:.1f}x below, {hi / max(spreads):.1f}x above",
                 f"{shape_lim / max(shape_all):.0f}x"])
    return _table(["data", "takes", "rate (Hz)", "fastest speed (mm/s)",
                   "farthest from the face centre (mm)", "spread (mm)",
                   "shape difference between takes (mm RMS)"], rows, "lrrrrrr")


# docs/settings.md -----------------------------------------------------------------------------

SETTINGS_PAGE = "docs/settings.md"


def _yaml_value(v) -> str:
    return "`" + json.dumps(v, ensure_ascii=False) + "`"


def _allowed(spec: dict) -> str:
    parts = []
    types = spec.get("type")
    if isinstance(types, list):
        parts.append(" or ".join(types))
    elif types:
        parts.append(types)
    if "enum" in spec:
        parts = ["one of " + ", ".join(f"`{v}`" for v in spec["enum"])]
    for key, sym in (("minimum", "≥"), ("exclusiveMinimum", ">"), ("maximum", "≤"),
                     ("exclusiveMaximum", "<")):
        if key in spec:
            parts.append(f"{sym} {spec[key]:g}")
    items = spec.get("items")
    if isinstance(items, dict):
        inner = _allowed(items)
        if inner:
            parts.append(f"items: {inner}")
    if "minItems" in spec and spec.get("minItems") == spec.get("maxItems"):
        parts.append(f"{spec['minItems']} items")
    elif "minItems" in spec:
        parts.append(f"at least {spec['minItems']} item(s)")
    if "pattern" in spec:
        parts.append(f"pattern `{spec['pattern']}`")
    return ", ".join(parts)


def _settings_rows(props: dict, prefix: str = "") -> list[list[str]]:
    rows = []
    for name, spec in props.items():
        key = f"{prefix}{name}"
        if "properties" in spec and spec.get("type") == "object":
            rows += _settings_rows(spec["properties"], key + ".")
            continue
        default = _yaml_value(spec["default"]) if "default" in spec else "—"
        extra = spec.get("additionalProperties")
        if spec.get("type") == "object" and isinstance(extra, dict):
            rows.append([f"`{key}`", default, "a mapping of names to entries",
                         _esc(spec.get("description", "")) or "—"])
            if "properties" in extra:
                rows += _settings_rows(extra["properties"], f"{key}.<name>.")
            elif extra.get("type") == "object":
                pass
            continue
        rows.append([f"`{key}`", default, _esc(_allowed(spec)),
                     _esc(spec.get("description", "")) or "—"])
    return rows


@block(SETTINGS_PAGE, "settings", [], "workflow/schemas/config.schema.yaml")
def _settings(src: Sources) -> str:
    schema = _schema(src)
    return _table(["setting", "default", "allowed", "what it sets"],
                  _settings_rows(schema["properties"]))


# docs/outputs.md ------------------------------------------------------------------------------

OUTPUTS_PAGE = "docs/outputs.md"


@block(OUTPUTS_PAGE, "outputs-manifest", ["paper"], "results/paper/manifest.tsv")
def _outputs_manifest(src: Sources) -> str:
    root = src.root("paper")
    manifest = _tsv(root / "manifest.tsv")
    datasets = set(_datasets(root).values())
    groups: dict[str, list] = {}
    for _, r in manifest.iterrows():
        parts = list(Path(r["path"]).relative_to(Path("results") / root.name).parts)
        if parts[0] in datasets:
            parts[0] = "{dataset}"
        elif parts[0] == "lips" and len(parts) > 2:
            parts[1] = "{lip_subject}"
            parts[-1] = re.sub(r"_seed\d+\.", "_seed{seed}.", parts[-1])
        elif parts[0] == "virtual" and len(parts) > 2:
            stem = parts[2].split(".")[0]
            parts[1:] = ["{subject}", re.sub(r"_s\d+$", "_s{nn}", stem)
                         + "." + parts[2].split(".", 1)[1]]
        elif parts[0] == "sweeps" and len(parts) > 3:
            parts[1:] = ["{sweep}", "{dataset}", "{point}.tsv"]
        pattern = "/".join(parts)
        g = groups.setdefault(pattern, [r["schema_id"], r["step"], 0])
        g[2] += 1
    rows = [[f"`{p}`", f"`{s}`", f"`{step}`", str(n)] for p, (s, step, n) in groups.items()]
    return (f"{len(manifest)} files of {len(groups)} kinds:\n\n"
            + _table(["path under results/paper/", "schema", "rule", "files"], rows, "lllr"))


# docs/real-data.md ----------------------------------------------------------------------------

REAL_PAGE = "docs/real-data.md"


@block(REAL_PAGE, "real-datasets", ["real"],
       "results/real/<dataset>/qr/rank.tsv, qr/r_values.tsv, qr/redundancy.tsv, "
       "data/sentences.tsv")
def _real_datasets(src: Sources) -> str:
    rows = []
    tol = ""
    for label, folder, rank, r_values in _study_datasets(src, "real"):
        tol = _tolerances(rank)
        at = _paper_eps(rank)
        sent = _tsv(folder / "data" / "sentences.tsv")
        train = sent[sent["role"] == "train"]
        head = _range(train["head_fit_rms_mm"].astype(float).tolist(), lambda x: _num(x, 2))
        copies = len(_tsv(folder / "qr" / "redundancy.tsv"))
        rows.append([label, f"{int(at['rows']):,} x {at['markers']}", _eps_ranks(rank),
                     _pivots(r_values), head, str(copies)])
    return _table(["dataset", "A (rows x markers)", f"epsilon-rank at {tol} mm",
                   "first 5 pivots", "head-fit RMS residual (mm)", "copy intervals reported"],
                  rows, "llllrr")


def _heldout_table(src: Sources, study: str, ks: Sequence[int]) -> str:
    rows = []
    for label, folder, _, _ in _study_datasets(src, study):
        curve = _curve_at(folder, ks)
        if curve is None:
            continue
        rows.append([label] + [f"{_num(curve[k]['mean_abs_error_mm'])} mm / "
                               f"{_pct(curve[k]['rel_error_per_marker'], 0)}"
                               if k in curve else "—" for k in ks])
    return _table(["dataset", *[f"k = {k}" for k in ks]], rows, "l" + "r" * len(ks))


@block(REAL_PAGE, "real-headline", ["real"], "results/real/<dataset>/qr/rank.tsv")
def _real_headline(src: Sources) -> str:
    return _headline(src, "real")


@block(REAL_PAGE, "real-heldout", ["real"], "results/real/<dataset>/eval/error_curve.tsv")
def _real_heldout(src: Sources) -> str:
    return _heldout_table(src, "real", [1, 5, 10, 20])


@block(REAL_PAGE, "real-sweep", ["real"], "results/real/tables/sweep_*.tsv")
def _real_sweep(src: Sources) -> str:
    out = []
    for path in sorted((src.root("real") / "tables").glob("sweep_*.tsv")):
        t = _tsv(path)
        rows = [[r["dataset"], r["marker_subset"] or "—", r["n_markers"], r["k"],
                 f"{float(r['tolerance_mm']):g}", r["epsilon_rank"],
                 " ".join(r["first_pivots"].split(",")[:5]),
                 _num(r["heldout_mean_abs_error_mm"]) if r["heldout_mean_abs_error_mm"] else "—"]
                for _, r in t.iterrows()]
        out += [f"`{path.name}`:", "", _table(
            ["dataset", "marker subset", "markers", "k", "ε (mm)", "epsilon-rank",
             "first 5 pivots", "held-out error at k (mm)"], rows, "llrrrrlr"), ""]
    return "\n".join(out).rstrip("\n") or "No sweep in the real-data study."


# docs/dense.md --------------------------------------------------------------------------------

DENSE_PAGE = "docs/dense.md"


@block(DENSE_PAGE, "dense-datasets", ["dense"],
       "results/dense/<dataset>/qr/rank.tsv and qr/r_values.tsv")
def _dense_datasets(src: Sources) -> str:
    rows, notes = [], []
    tol = ""
    for label, _, rank, r_values in _study_datasets(src, "dense"):
        tol = _tolerances(rank)
        at = _paper_eps(rank)
        r = r_values["r"].astype(float)
        ranked = r.iloc[:int(at["numerical_rank"])]
        rows.append([label, f"{int(at['rows']):,} x {at['markers']}",
                     f"{int(at['zero_rows']):,}", at["numerical_rank"], _eps_ranks(rank),
                     _num(ranked.min()), _pivots(r_values)])
        if at["note"]:
            notes.append(f"- {label}: {at['note']}.")
    out = _table(["dataset", "A (rows x points)", "zero rows", "numerical rank",
                  f"epsilon-rank at {tol} mm", "smallest r_kk within the rank (mm)",
                  "first 5 pivots"], rows, "llrrlrl")
    return out + ("\n\nWhat `rank.tsv` says where there are fewer rows than points:\n\n"
                  + "\n".join(notes) if notes else "")


@block(DENSE_PAGE, "dense-headline", ["dense"], "results/dense/<dataset>/qr/rank.tsv")
def _dense_headline(src: Sources) -> str:
    return _headline(src, "dense")


@block(DENSE_PAGE, "dense-heldout", ["dense"], "results/dense/<dataset>/eval/error_curve.tsv")
def _dense_heldout(src: Sources) -> str:
    return _heldout_table(src, "dense", [1, 10, 20, 40])


# docs/workflow.md -----------------------------------------------------------------------------

@block("docs/workflow.md", "talkers-config", [], "config/talkers.yaml")
def _talkers_config(src: Sources) -> str:
    text = (src.repo / "config" / "talkers.yaml").read_text()
    return "```yaml\n" + text.rstrip("\n") + "\n```"


# ---- figures ---------------------------------------------------------------------------------

FIGURES: list[Figure] = [
    Figure("paper_regions_S2a.png", "paper", "S2a/fit/regions_k10.png"),
    Figure("paper_orthogonal_S2a.png", "paper", "S2a/fit/orthogonal_k10.png"),
    Figure("paper_selected_markers.png", "paper", "figures/selected_markers.png"),
    Figure("paper_r_values.png", "paper", "figures/r_values.png"),
    Figure("paper_sentence_sweep_S1.png", "paper", "S1/qr/sentence_sweep_plot.png"),
    Figure("paper_animation_still_S2a.png", "paper", "S2a/anim/heldout_still.png"),
    Figure("paper_trajectory_S1.png", "paper", "S1/eval/trajectory.png"),
    Figure("paper_error_curves.png", "paper", "figures/error_curves.png"),
    Figure("paper_gaps_S1.png", "paper", "S1/data/gaps.png"),
    Figure("paper_comparison.png", "paper", "figures/paper_comparison.png"),
    Figure("paper_lips_modes_virtual.png", "paper", "lips/virtual/modes_plot.png"),
    Figure("paper_lips_mesh_virtual.png", "paper", "lips/virtual/mesh.png"),
    Figure("paper_lips_mesh_grid_talker.png", "paper", "lips/grid_talker/mesh.png"),
    Figure("paper_lips_modes_grid_talker.png", "paper", "lips/grid_talker/modes_plot.png"),
    Figure("real_regions_grid_t1.png", "real", "grid_t1/fit/regions_k10.png"),
    Figure("real_r_values.png", "real", "figures/r_values.png"),
    Figure("real_sweep_grid_landmarks.png", "real", "figures/sweep_grid_landmarks.png"),
    Figure("dense_regions_dense468.png", "dense", "dense468/fit/regions_k10.png"),
]


# ---- the command -----------------------------------------------------------------------------

@dataclass
class Outcome:
    """What a run found, one line each: differences from the sources (``differs``), what was
    written, what was skipped and why, and what neither mode can fix (``problems``: a page or a
    block's markers missing)."""

    differs: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    written: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    unchanged: int = 0


def header(b: Block) -> str:
    return (f"<!-- written by {COMMAND} from {b.source}; edit the generator "
            "(src/facemotion/study/pages.py), not this block -->")


def render(b: Block, src: Sources) -> str:
    """The text between a block's markers."""
    # blank lines round the header: every renderer then takes it as a comment of its own
    return f"\n{header(b)}\n\n{b.render(src).strip(chr(10))}\n\n"


def _missing_source(b: Block, src: Sources) -> str | None:
    for s in b.studies:
        if src.study(s) is None:
            return f"no finished study at {src.results / s} (run {STUDIES.get(s, s)})"
    if b.needs_shared_data and (src.shared_data is None or not src.shared_data.is_dir()):
        return f"the shared data are not at {src.shared_data}"
    return None


def _first_difference(old: str, new: str) -> str:
    a, b = old.splitlines(), new.splitlines()
    for i, (x, y) in enumerate(zip(a, b, strict=False), 1):
        if x != y:
            return f"line {i}: {x[:70]!r} here, {y[:70]!r} generated"
    if len(a) != len(b):
        return f"{len(a)} lines here, {len(b)} generated"
    return "whitespace"


def parse_blocks(text: str, where: str) -> dict[str, re.Match]:
    """The generated blocks of a page by name; InputError for unbalanced or repeated markers."""
    found: dict[str, re.Match] = {}
    for m in BLOCK.finditer(text):
        if m.group("name") in found:
            raise InputError(f"{where}: block {m.group('name')} appears twice")
        found[m.group("name")] = m
    opened = [m.group("name") for m in MARKER.finditer(text) if m.group("end") == "start"]
    closed = [m.group("name") for m in MARKER.finditer(text) if m.group("end") == "end"]
    for name in set(opened) | set(closed):
        if name not in found or opened.count(name) != 1 or closed.count(name) != 1:
            raise InputError(f"{where}: the markers of block {name} do not pair up "
                             f"(<!-- generated:{name}:start --> ... "
                             f"<!-- generated:{name}:end -->)")
    return found


def pages(repo: Path) -> list[str]:
    """Every page that may hold generated blocks: README.md and docs/*.md, plus the pages of
    ``BLOCKS`` (so a missing page is reported)."""
    found = ["README.md"] + sorted(str(p.relative_to(repo)) for p in (repo / "docs").glob("*.md"))
    return list(dict.fromkeys(found + [b.page for b in BLOCKS]))


def run(repo: Path, results: Path, shared_data: Path | None = None,
        check: bool = False) -> Outcome:
    """Regenerate (or with ``check``, compare) every block and figure of the docs."""
    repo, results = Path(repo), Path(results)
    src = Sources(repo, results, shared_data)
    out = Outcome()
    by_page: dict[str, dict[str, Block]] = {}
    for b in BLOCKS:
        by_page.setdefault(b.page, {})[b.name] = b
    for page in pages(repo):
        path = repo / page
        if not path.is_file():
            out.problems.append(f"{page}: missing (it should hold the blocks "
                               f"{', '.join(by_page.get(page, {}))})")
            continue
        text = path.read_text()
        found = parse_blocks(text, page)
        ours = by_page.get(page, {})
        for name in found:
            if name not in ours:
                writer = EXTERNAL.get(name, "no command known to facemotion docs")
                out.skipped.append(f"{page}: block {name} skipped: written by {writer}")
        for name in ours:
            if name not in found:
                out.problems.append(f"{page}: block {name} is missing (add "
                                   f"<!-- generated:{name}:start --> and its end marker)")
        new_text, pos, changed = [], 0, []
        for name, m in sorted(found.items(), key=lambda kv: kv[1].start()):
            new_text.append(text[pos:m.start("body")])
            body = m.group("body")
            b = ours.get(name)
            if b is not None:
                reason = _missing_source(b, src)
                if reason:
                    out.skipped.append(f"{page}: block {name} skipped: {reason}")
                else:
                    generated = render(b, src)
                    if generated == body:
                        out.unchanged += 1
                    else:
                        changed.append(name)
                        out.differs.append(f"{page}: block {name} differs from its sources "
                                           f"({_first_difference(body, generated)})")
                        body = generated
            new_text.append(body)
            pos = m.end("body")
        new_text.append(text[pos:])
        if changed and not check:
            from facemotion.io.atomic import atomic_path

            with atomic_path(path) as tmp:
                tmp.write_text("".join(new_text))
            out.written.append(f"{page}: wrote {', '.join(changed)}")
    _figures(src, out, check)
    return out


def _figures(src: Sources, out: Outcome, check: bool) -> None:
    fig_dir = src.repo / FIGURE_DIR
    wanted = {f.name for f in FIGURES}
    for f in FIGURES:
        target = fig_dir / f.name
        rel = f"{FIGURE_DIR}/{f.name}"
        root = src.study(f.study)
        if root is None:
            out.skipped.append(f"{rel} skipped: no finished study at {src.results / f.study} "
                               f"(run {STUDIES.get(f.study, f.study)})")
            continue
        source = root / f.path
        if not source.is_file():
            raise InputError(f"{source}: not found (the docs show it as {rel})")
        data = source.read_bytes()
        if target.is_file() and target.read_bytes() == data:
            out.unchanged += 1
            continue
        out.differs.append(f"{rel} differs from results/{f.study}/{f.path}"
                           if target.is_file() else f"{rel} is missing "
                           f"(a copy of results/{f.study}/{f.path})")
        if not check:
            fig_dir.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)
            out.written.append(f"{rel}: copied from results/{f.study}/{f.path}")
    if fig_dir.is_dir():
        for p in sorted(fig_dir.iterdir()):
            if p.is_file() and p.name not in wanted:
                out.differs.append(f"{FIGURE_DIR}/{p.name}: generated by nothing "
                                   "(make pages deletes it)")
                if not check:
                    p.unlink()
                    out.written.append(f"{FIGURE_DIR}/{p.name}: deleted")
