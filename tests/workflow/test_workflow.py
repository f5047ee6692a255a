"""The smoke workflow end to end: outputs with sidecars, byte-identical reruns, the report,
and a second study beside it in the same directory.

Runs `snakemake` on config/smoke.yaml in two fresh directories (tiny virtual subjects and a
tiny lip model) and compares every output's checksum between the two runs.
"""

import hashlib
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pandas as pd
import pytest
from helpers import REPO

SNAKEMAKE = [sys.executable, "-m", "snakemake"]
pytestmark = pytest.mark.workflow


def run_snakemake(workdir, *args, check=True, extra_config=None):
    configs = [str(REPO / "config" / "smoke.yaml")]
    if extra_config is not None:
        extra = Path(workdir) / "extra_config.yaml"
        extra.write_text(extra_config)
        configs.append(str(extra))
    cmd = SNAKEMAKE + ["-s", str(REPO / "Snakefile"), "--directory", str(workdir),
                       "--cores", "2", "--configfile", *configs, *args]
    env = dict(os.environ, PYTHONHASHSEED="0")
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stdout[-4000:]}\n"
                             f"{proc.stderr[-6000:]}")
    return proc


def checksums(root: Path, study: str = "smoke") -> dict[str, str]:
    out = {}
    for p in sorted((root / "results" / study).rglob("*")):
        if p.is_file() and not {"logs", "benchmarks"} & set(p.parts) and p.suffix != ".html":
            out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


@pytest.fixture(scope="module")
def smoke_runs(tmp_path_factory):
    a = tmp_path_factory.mktemp("run_a")
    b = tmp_path_factory.mktemp("run_b")
    proc = run_snakemake(a)
    (a / "terminal.txt").write_text(proc.stdout + proc.stderr)
    run_snakemake(b)
    return a, b


def test_outputs_exist_with_sidecars(smoke_runs):
    a, _ = smoke_runs
    assert [p.name for p in (a / "results").iterdir()] == ["smoke"]  # the study's own root
    res = a / "results" / "smoke"
    for ds in ("S1", "S2a"):
        for rel in ("data/displacements.npz", "data/gap_report.tsv", "qr/r_values.tsv",
                    "qr/rank.tsv", "qr/redundancy.tsv", "qr/sentence_sweep.tsv",
                    "qr/stability.tsv", "qr/optimality.tsv", "fit/coefficients_k4.tsv",
                    "eval/error_curve.tsv", "eval/trajectory_errors.tsv"):
            assert (res / ds / rel).is_file(), rel
        for tsv in (res / ds).rglob("*.tsv"):
            side = tsv.with_name(tsv.stem + ".meta.json")
            assert side.is_file(), f"no sidecar for {tsv}"
            meta = json.loads(side.read_text())
            assert meta["schema_id"].startswith("facemotion/")
            digest = hashlib.sha256(tsv.read_bytes()).hexdigest()
            assert meta["outputs"][0]["sha256"] == digest
        for png in (res / ds).rglob("*.png"):
            # figures.formats defaults to PNG only
            assert not png.with_suffix(".pdf").exists() and not png.with_suffix(".svg").exists()
            assert png.with_name(png.stem + ".meta.json").is_file()
        # the animation: MP4 by default, and a page that plays it in the report
        mp4 = res / ds / "anim" / "heldout.mp4"
        assert mp4.read_bytes()[4:8] == b"ftyp"
        page = (res / ds / "anim" / "heldout_page.html").read_text()
        assert 'src="data:video/mp4;base64,' in page
    table = pd.read_csv(res / "tables" / "selected_markers.tsv", sep="\t", dtype=str)
    assert list(table.columns) == ["order", "S1", "S2a"]
    # tables and figures across datasets, drawn by aggregation rules: each one's sidecar
    # names the per-dataset tables it was made from
    for rel, step, inputs in (
            ("figures/error_curves", "summarise_heldout", ["eval/error_curve.tsv"]),
            ("tables/selected_markers", "summarise_ranking", ["qr/r_values.tsv", "qr/rank.tsv"]),
            ("figures/r_values", "summarise_ranking", ["qr/r_values.tsv", "qr/rank.tsv"])):
        meta = json.loads((res / f"{rel}.meta.json").read_text())
        assert meta["step"] == step, rel
        assert sorted(i["path"] for i in meta["inputs"]) == sorted(
            f"results/smoke/{ds}/{f}" for ds in ("S1", "S2a") for f in inputs), rel
    manifest = pd.read_csv(res / "manifest.tsv", sep="\t", dtype=str)
    assert "results/smoke/S1/qr/r_values.tsv" in set(manifest["path"])
    assert "results/smoke/summary.txt" in set(manifest["path"])
    assert (res / "lips" / "virtual" / "reconstruction.tsv").is_file()
    # the papers against this study: every statement has a row, none without a verdict
    cmp = pd.read_csv(res / "tables" / "paper_comparison.tsv", sep="\t", dtype=str,
                      keep_default_na=False)
    assert len(cmp) >= 40 and (cmp["verdict"] != "").all()
    assert set(cmp["paper"]) == {"Lucero & Munhall 2008", "Basu & Pentland 1997"}
    s1 = cmp[cmp["statement"] == "S1, pivot 1"].iloc[0]
    assert s1["paper_value"] == "40 (lips)" and s1["verdict"] != "not measured"
    assert (cmp[cmp["statement"].str.startswith("S2b")]["verdict"] == "not measured").all()


def test_every_per_dataset_figure_is_titled_with_its_dataset(smoke_runs):
    from helpers import untitled_subject

    a, _ = smoke_runs
    metas = [json.loads(p.read_text()) for p in (a / "results" / "smoke").rglob("*.meta.json")]
    figures = [m for m in metas if m["schema_id"].startswith("facemotion/figure/")
               and "dataset" in m["config"].get("wildcards", {})]
    assert len(figures) >= 10
    assert [(m["outputs"][0]["path"], untitled_subject(m)) for m in figures
            if untitled_subject(m)] == []
    # the check rejects a figure whose titles do not name its dataset
    bad = dict(figures[0], titles=["Held-out prediction error"])
    assert untitled_subject(bad) == (bad["config"]["params"].get("label")
                                     or bad["config"]["wildcards"]["dataset"])


def test_rerun_is_byte_identical(smoke_runs):
    a, b = smoke_runs
    ca, cb = checksums(a), checksums(b)
    assert ca.keys() == cb.keys()
    differ = [k for k in ca if ca[k] != cb[k]]
    assert not differ, f"outputs differ between identical runs: {differ}"


def test_nothing_to_do_on_rerun_and_param_change_reruns_only_dependents(smoke_runs):
    a, _ = smoke_runs
    proc = run_snakemake(a, "-n")
    assert "Nothing to be done" in proc.stdout + proc.stderr
    proc = run_snakemake(a, "-n", extra_config="qr:\n  tolerances_mm: [0.3]\n")
    out = proc.stdout + proc.stderr
    assert "rank_markers" in out
    assert "load_dataset" not in out and "simulate_subject" not in out


def test_figure_formats_setting_adds_vector_files(smoke_runs):
    a, _ = smoke_runs
    proc = run_snakemake(a, "-n", "--quiet", "rules",
                         extra_config="figures:\n  formats: [png, svg]\n")
    out = proc.stdout + proc.stderr
    # every rule that draws a figure reruns for its new SVG files
    for rule in ("rank_markers", "fit_regions", "evaluate_heldout", "animate_heldout",
                 "load_dataset", "fit_lip_model"):
        assert rule in out, rule
    proc = run_snakemake(a, "-n", extra_config="figures:\n  formats: [svg]\n", check=False)
    assert proc.returncode != 0 and "formats" in proc.stdout + proc.stderr


def dry_run_rules(proc) -> set[str]:
    """The rules of the jobs a dry run would run (its 'Job stats' table)."""
    text = proc.stdout + proc.stderr
    if "Nothing to be done" in text:
        return set()
    stats = text[text.index("Job stats:"):].split("\n")[3:]
    rules = set()
    for line in stats:
        parts = line.split()
        if len(parts) != 2 or parts[0] == "total":
            break
        rules.add(parts[0])
    return rules


# rules that gather every output (they rerun whenever anything does)
GATHER = {"summarise_study", "write_manifest", "all", "compare_with_papers"}


@pytest.mark.parametrize("setting, reruns", [
    ("qr:\n  tolerances_mm: [0.3]\n", {"rank_markers", "summarise_ranking", "render_face_page"}),
    ("qr:\n  table_orders: 5\n", {"summarise_ranking"}),
    ("qr:\n  noise_mm: 0.3\n", {"find_redundant_markers"}),
    ("qr:\n  optimality_k_max: 2\n", {"compare_subsets"}),
    ("qr:\n  replicates: 10\n", {"sweep_sentences"}),
    ("eval:\n  trajectory_k: 3\n", {"evaluate_heldout", "summarise_heldout"}),
    ("fit:\n  grid_n: 30\n", {"fit_regions", "render_face_page"}),
    ("animation:\n  grid_n: 12\n", {"animate_heldout"}),
    ("gaps:\n  max_interp_s: 0.2\n", None),  # the data: everything after loading
])
def test_a_changed_setting_reruns_exactly_what_reads_it(smoke_runs, setting, reruns):
    """A setting reruns the jobs that read it, the aggregations of their outputs and the
    rules that gather every output, nothing else."""
    a, _ = smoke_runs
    got = dry_run_rules(run_snakemake(a, "-n", extra_config=setting)) - GATHER
    if reruns is None:
        assert "load_dataset" in got and "simulate_subject" not in got
        assert "fit_lip_model" not in got
    else:
        assert got == reruns


def dry_run_jobs(proc) -> list[tuple[str, str]]:
    """(rule, message) of each job a dry run lists ("Job N: <message>" lines)."""
    text = proc.stdout + proc.stderr
    return [(m.split()[0].rstrip(":"), m) for m in re.findall(r"^Job \d+: (.+)$", text, re.M)]


# the aggregations: tables and figures across datasets, the comparison, summary and manifest
AGGREGATIONS = GATHER | {"summarise_ranking", "summarise_heldout", "render_face_page"}


def test_a_new_subject_runs_only_its_own_jobs_and_the_aggregations(smoke_runs, tmp_path):
    """The smoke study's two subjects are complete; a sheet with a third subject plans the
    third subject's jobs, one per rule, and the aggregations, never a job of the first two."""
    a, _ = smoke_runs
    sheet = (REPO / "config" / "smoke_subjects.tsv").read_text().rstrip("\n").split("\n")
    new = sheet[-1].split("\t")
    new[0], new[6], new[7] = "S2b", "S2b", "3"  # subject, simulate, seed
    (tmp_path / "three.tsv").write_text("\n".join([*sheet, "\t".join(new)]) + "\n")
    proc = run_snakemake(a, "-n", "--config", f"subjects={tmp_path / 'three.tsv'}")
    jobs = dry_run_jobs(proc)
    own = [(rule, msg) for rule, msg in jobs if rule not in AGGREGATIONS]
    assert own and all(msg.split()[1].startswith("S2b") for _, msg in own), own
    per_rule = {}
    for rule, _ in own:
        per_rule[rule] = per_rule.get(rule, 0) + 1
    assert per_rule == dict.fromkeys(
        ["simulate_subject", "load_dataset", "rank_markers", "find_redundant_markers",
         "sweep_sentences", "compare_subsets", "fit_regions", "evaluate_heldout",
         "animate_heldout", "design_markers"], 1), per_rule
    assert {rule for rule, _ in jobs} & AGGREGATIONS == AGGREGATIONS


def report_entries(html: str) -> dict:
    """The report's entries (path -> caption, job properties) from its report.html."""
    start = html.index("var results = ", html.index("<script id=\"results\">")) + len(
        "var results = ")
    return json.JSONDecoder().raw_decode(html[start:])[0]


def caption_problems(path: str, entry: dict, root: Path) -> list[str]:
    """What is wrong with a report entry's rendered caption: a docutils message, an empty
    field, a dataset (lip subject, sweep) it does not name, a results/ path that does not
    exist under ``root``."""
    caption = entry["caption"]
    problems = [] if caption.strip() else [f"{path}: empty caption"]
    for bad in ("System Message", "system-message", "problematic", "<strong></strong>",
                '<tt class="docutils literal"></tt>', "``"):
        if bad in caption:
            problems.append(f"{path}: {bad!r} in the caption")
    wildcards = dict(w.split("=", 1) for w in
                     filter(None, (entry["job_properties"]["wildcards"] or "").split(", ")))
    for key in ("dataset", "lip_subject", "sweep"):
        if key in wildcards and f"<strong>{wildcards[key]}</strong>" not in caption:
            problems.append(f"{path}: the caption does not name {key} {wildcards[key]}")
    for named in re.findall(r"results/[^\s<\"&]+", caption):
        if not (root / named).exists():
            problems.append(f"{path}: {named} does not exist")
    return problems


def test_report_captions_render_and_name_their_dataset(smoke_runs):
    """Every caption renders without a docutils message or an empty field; a per-dataset (or
    per-lip-subject, per-sweep) entry's caption names its own; every results/ path a caption
    names exists. The same check finds the faults of a caption without its wildcard."""
    a, _ = smoke_runs
    run_snakemake(a, "--report", "results/smoke/report.zip")
    zf = zipfile.ZipFile(a / "results" / "smoke" / "report.zip")
    names = zf.namelist()
    for expected in ("r_values.png", "sentence_sweep_plot.png", "regions_k4.png",
                     "error_curve_plot.png", "mesh.png", "reconstruction.tsv",
                     "heldout_page.html", "heldout_still.png",
                     "paper_comparison.png"):
        assert any(n.endswith(expected) for n in names), expected
    html = zf.read(next(n for n in names if n.endswith("report.html"))).decode()
    entries = report_entries(html)
    assert len(entries) >= 25  # 11 per dataset (2), the lip model and the summaries
    problems = [p for path, e in entries.items() for p in caption_problems(path, e, a)]
    assert not problems, problems
    assert "System Message" not in html and "results/smoke/manifest.tsv" in html
    # a caption rendered without its wildcard (the fault of every per-dataset caption when
    # one job ran over all datasets), and a path that does not exist
    broken = {"caption": 'for dataset <tt class="docutils literal"></tt> '
                         "(results/tables/none.tsv)",
              "job_properties": {"wildcards": "dataset=S1"}}
    found = caption_problems("x", broken, a)
    assert len(found) == 3, found


def test_bad_config_value_is_rejected_at_parse_time(tmp_path):
    for bad, name in (("qr:\n  tolerances_mm: [-1]\n", "tolerances_mm"),
                      ("sweeps:\n  s:\n    k: [0]\n", "k"),
                      ("sweeps:\n  s:\n    k: [60]\n", "sweeps.s.k"),
                      ("animation:\n  formt: gif\n", "formt"),
                      ("shared_data: /nonexistent\nlips:\n  subjects:\n    g:\n"
                       "      source: grid\n", "lips.subjects.g")):
        proc = run_snakemake(tmp_path, "-n", check=False, extra_config=bad)
        assert proc.returncode != 0, bad
        assert name in proc.stdout + proc.stderr, (bad, proc.stderr[-2000:])
        assert not (tmp_path / "results").exists()


def test_terminal_output_is_short_and_ends_with_a_summary(smoke_runs):
    a, _ = smoke_runs
    text = (a / "terminal.txt").read_text()
    assert "Shell command" not in text
    # each job says why it runs (the profile shows Snakemake's reasons: docs/reruns.md); those
    # lines list files, every other line is short
    assert "Reason: Missing output files" in text
    longest = max((x for x in text.splitlines() if not x.startswith("Reason:")),
                  key=len)
    assert len(longest) < 300, longest[:200]
    tail = text[text.index("facemotion study 'smoke'"):]
    assert "every output is under results/smoke/" in tail
    summary = (a / "results" / "smoke" / "summary.txt").read_text()
    assert summary in tail
    # the headline numbers are the tables' own
    ranks = pd.read_csv(a / "results" / "smoke" / "tables" / "rank_summary.tsv", sep="\t")
    s1 = ranks[(ranks["dataset"] == "S1")
               & (ranks["tolerance_from"] == "qr.tolerances_mm")].sort_values("tolerance_mm")
    assert " / ".join(str(r) for r in s1["epsilon_rank"]) in summary
    noise = ranks[(ranks["dataset"] == "S1") & (ranks["tolerance_from"] == "noise_level")]
    assert f"{noise['epsilon_rank'].iloc[0]} of {noise['markers'].iloc[0]}" in summary
    assert "k for 1 mm" in summary and "prediction" in summary
    sel = pd.read_csv(a / "results" / "smoke" / "tables" / "selected_markers.tsv", sep="\t",
                      dtype=str)
    assert " ".join(sel["S1"][:5]) in summary
    # which sentences trained and which were held out, from the dataset's own table
    sent = pd.read_csv(a / "results" / "smoke" / "S1" / "data" / "sentences.tsv", sep="\t")
    n_train, n_held = (sent["role"] == "train").sum(), (sent["role"] == "heldout").sum()
    assert f"  S1: trained on {n_train} ({sent['sentence'].iloc[0]}" in summary
    assert f"; held out {n_held} (" in summary
    assert "--report results/smoke/report.html" in tail


def test_two_studies_in_one_directory_never_overwrite_each_other(smoke_runs):
    """A second study (its own name and settings) beside the smoke study, in either order."""
    _, b = smoke_runs
    before = checksums(b, "smoke")
    other = ("study: other\nfit:\n  k: [5]\nanimation:\n  enabled: false\n"
             "lips:\n  subjects: {}\n")
    run_snakemake(b, extra_config=other)
    assert sorted(p.name for p in (b / "results").iterdir()) == ["other", "smoke"]
    assert checksums(b, "smoke") == before  # the first study is untouched
    assert (b / "results" / "other" / "S1" / "fit" / "coefficients_k5.tsv").is_file()
    assert not (b / "results" / "other" / "S1" / "fit" / "coefficients_k4.tsv").exists()
    # both are complete: neither run made the other out of date
    for extra in (None, other):
        proc = run_snakemake(b, "-n", extra_config=extra)
        assert "Nothing to be done" in proc.stdout + proc.stderr
    # each study's manifest and report hold its own outputs only
    for study, extra in (("smoke", None), ("other", other)):
        manifest = pd.read_csv(b / "results" / study / "manifest.tsv", sep="\t")
        assert manifest["path"].str.startswith(f"results/{study}/").all()
        run_snakemake(b, "--report", f"results/{study}/report.zip", extra_config=extra)
        names = zipfile.ZipFile(b / "results" / study / "report.zip").namelist()
        mine, theirs = (4, 5) if study == "smoke" else (5, 4)
        assert any(n.endswith(f"regions_k{mine}.png") for n in names), study
        assert not any(n.endswith(f"regions_k{theirs}.png") for n in names), study
