# Configuration, subject sheet and datasets; helpers that list each stage's outputs.
import os
import sys
from pathlib import Path
from types import SimpleNamespace

import yaml
from snakemake.utils import min_version

from facemotion.errors import InputError
from facemotion.study.invocation import (
    ParseGuard,
    invocation_dir,
    remember_invocation,
    resolve_path,
    same_study_command,
    sample_benchmarks_every,
)
from facemotion.study.summary import closing_message, study_name
from facemotion.study.settings import (
    DataCounts,
    check_lip_frames,
    check_settings,
    check_sweep,
    data_counts,
    exit_on_error,
    validate_config,
    validate_sheet,
)
from facemotion.study.sheet import read_subject_sheet, resolve_datasets

min_version("9.13")  # pathvars (<results>)

# The repository of this workflow, from this file's folder (workflow.basedir is the *main*
# Snakefile's folder: another project's when this workflow is used as a module; source_path
# gives a source-cache copy). None when the workflow is read from a remote (github(...)).
_HERE = Path(workflow.current_basedir.get_path_or_uri(secret_free=True))
REPO = _HERE.parents[1] if _HERE.is_dir() else None

# A failed parse (a bad setting, a missing sheet) leaves no .snakemake/ behind.
_PARSE = ParseGuard(workflow.logger_manager.get_logfile())
# Where the user typed the command: a relative path given with --config is read from there.
_CLI = dict(workflow.config_settings.config)
INVOCATION_DIR = invocation_dir(workflow.rundir, workflow.overwrite_workdir)
remember_invocation(INVOCATION_DIR)
# benchmark: files sampled every 5 s, not twice a second (4 s of CPU in the default study);
# their wall times are unchanged, and each job's log has its exact peak memory
sample_benchmarks_every(5.0)

# With no --configfile the default study's config is the base; --config values override it.
# `--config subjects=SHEET` alone runs the default settings on your sheet, one dataset per
# subject (the default config's paper datasets only make sense for its own sheet), as the
# study named after the sheet.
_OWN_SHEET = (
    "subjects" in config
)  # a sheet from --config, a config file or a host workflow
if not workflow.config_settings.configfiles:
    _user = dict(config)
    with open(workflow.source_path("../../config/config.yaml")) as _f:
        _base = yaml.safe_load(_f)
    if "subjects" in _user:
        _base["study"] = None  # named after the sheet below, unless --config study=NAME
    if "subjects" in _user and "datasets" not in _user:
        _base.pop("datasets", None)
        _base["default_datasets"] = True
    if "subjects" in _user and "lips" not in _user:
        # your own sheet: keep the built-in virtual lip talker, not the GRID one (shared data)
        _base["lips"]["subjects"] = {
            k: v for k, v in _base["lips"]["subjects"].items() if v["source"] != "grid"
        }
    _base.update(_user)
    config.clear()
    config.update(_base)

# Parse-time errors (a setting, the sheet, the data's counts): one line, exit status 1.
with exit_on_error():
    validate_config(config, workflow.source_path("../schemas/config.schema.yaml"))
    SHEET = resolve_path(
        config["subjects"],
        "subjects",
        from_command_line="subjects" in _CLI,
        inv=INVOCATION_DIR,
        repo=REPO,
        what="subject sheet",
    )
    SHARED_DATA = (
        resolve_path(
            config["shared_data"],
            "shared_data",
            from_command_line="shared_data" in _CLI,
            inv=INVOCATION_DIR,
            repo=REPO,
            what="shared-data folder",
            must_exist=False,
        )
        if config["shared_data"]
        else (REPO or Path.cwd()).parent / "shared" / "data"
    )
    STUDY = study_name(
        config["study"], workflow.config_settings.configfiles, SHEET, _OWN_SHEET
    )


# Every output of this study goes under results/<study>/ (<results> in the rules' paths), so
# two studies never overwrite each other. RESULTS is the same folder for params and scripts.
pathvars:
    results=f"results/{STUDY}",


RESULTS = workflow.pathvars.apply("<results>")
SKIPPED = []  # parts of the study left out, each said in one line (and in the summary)

with exit_on_error():
    SUBJECTS = read_subject_sheet(
        SHEET, shared_data=SHARED_DATA, virtual_dir=f"{RESULTS}/virtual"
    )
    for _ls, _spec in list(config["lips"]["subjects"].items()):
        if _spec["source"] == "grid" and not (SHARED_DATA / "grid").is_dir():
            if _spec.get("optional"):
                # the default study: only this lip subject reads the shared data
                SKIPPED.append(
                    f"lip subject {_ls}: it reads the GRID clips in {SHARED_DATA}/grid, which "
                    "is not there (set shared_data to include it)"
                )
                print(f"facemotion: skipped {SKIPPED[-1]}", file=sys.stderr)
                del config["lips"]["subjects"][_ls]
                continue
            raise InputError(
                f"setting lips.subjects.{_ls}: the GRID clips are read from "
                f"{SHARED_DATA}/grid, which does not exist; set shared_data or remove this "
                "lip subject"
            )
    validate_sheet(SHEET, workflow.source_path("../schemas/subjects.schema.yaml"))
    DATASETS = resolve_datasets(
        SUBJECTS,
        config["datasets"],
        heldout_fraction=config["heldout_fraction"],
        default_per_subject=config["default_datasets"],
    )


def _dataset_mesh_path(dataset):
    spec = (config.get("datasets") or {}).get(dataset) or {}
    if not spec.get("mesh"):
        return None
    return resolve_path(
        str(spec["mesh"]).replace("{shared_data}", str(SHARED_DATA)),
        f"datasets.{dataset}.mesh",
        from_command_line=False,
        inv=INVOCATION_DIR,
        repo=REPO,
        what="face mesh",
        must_exist=False,
    )


for _d in DATASETS:
    _m = _dataset_mesh_path(_d)
    if _m is not None and not Path(_m).is_file():
        raise InputError(f"setting datasets.{_d}.mesh: {_m} is not a file")


def dataset_mesh(wildcards):
    """The face mesh a dataset's maps are drawn on (setting datasets.<id>.mesh), or none."""
    m = _dataset_mesh_path(wildcards.dataset)
    return [str(m)] if m is not None else []


def dataset_mesh_labels(wildcards):
    spec = (config.get("datasets") or {}).get(wildcards.dataset) or {}
    return spec.get("mesh_labels", "L{i:03d}")


def dataset_recordings(wildcards):
    return SUBJECTS[DATASETS[wildcards.dataset].subject].recordings


def dataset_params(dataset):
    """Everything about a dataset that its outputs depend on (declared as rule params)."""
    ds = DATASETS[dataset]
    subj = SUBJECTS[ds.subject]
    return {
        "dataset": ds.id,
        "label": ds.label,
        "subject": subj.id,
        "format": subj.format,
        "units": subj.units,
        "head_markers": subj.head_markers,
        "exclude_markers": subj.exclude_markers,
        "include_markers": subj.include_markers,
        "copy_markers": [f"{t}={s}" for t, s in subj.copy_markers],
        "train": [i + 1 for i in ds.train],
        "heldout": [i + 1 for i in ds.heldout],
        "sentence_names": subj.sentence_names,
        "subject_prefix": subj.subject_prefix,
        "segments": (
            None if subj.segments is None else [s.to_param() for s in subj.segments]
        ),
    }


from facemotion.plots.save import figure_paths

FIGURE_FORMATS = config["figures"]["formats"]


def dataset_labels(datasets):
    """What a rule over several datasets knows of each one alone (params.per_dataset)."""
    return {d: {"label": DATASETS[d].label} for d in datasets}


def fig(path):
    """A figure's files: PNG for looking (and the report), PDF/SVG for papers if asked for
    (setting figures.formats)."""
    return figure_paths(path, FIGURE_FORMATS)


def fig_more(path):
    """A figure's files other than its PNG (the rule's `more` outputs)."""
    return fig(path)[1:]


def figs_more(pattern, datasets):
    """fig_more for each dataset of a rule over several datasets, in the order of `datasets`
    (the same number of files per dataset: run_per_dataset splits them back)."""
    return [f for d in datasets for f in fig_more(pattern.replace("{dataset}", d))]


def meta(path):
    return f"{path}.meta.json"


def all_outputs():
    out = []
    for d in DATASETS:
        base = f"<results>/{d}"
        out += [f"{base}/data/displacements.npz", f"{base}/data/gap_report.tsv"]
        out += [f"{base}/qr/r_values.tsv", f"{base}/qr/rank.tsv"]
        out += [f"{base}/qr/redundancy.tsv", f"{base}/qr/stability.tsv"]
        out += [f"{base}/qr/optimality.tsv"]
        out += [f"{base}/fit/coefficients_k{k}.tsv" for k in config["fit"]["k"]]
    for d in EVAL_DATASETS:
        out += [f"<results>/{d}/eval/error_curve.tsv"]
        if config["animation"]["enabled"]:
            out += [f"<results>/{d}/anim/heldout_still.png"]
    out += ["<results>/tables/selected_markers.tsv", "<results>/figures/r_values.png"]
    if EVAL_DATASETS:
        out += ["<results>/figures/error_curves.png"]
    for ls in config["lips"]["subjects"]:
        out += [f"<results>/lips/{ls}/reconstruction.tsv"]
    return out + sweep_outputs() + comparison_outputs() + ["<results>/summary.txt"]


def final_outputs():
    return all_outputs() + ["<results>/manifest.tsv"]


def print_closing_summary():
    """After a successful run (onsuccess): the summary, and how to open the report."""
    command = same_study_command(sys.argv, "--report", f"{RESULTS}/report.html")
    text = closing_message(RESULTS, workflow.start_time.timestamp(), command)
    if text:
        print(text, flush=True)


def summary_inputs(wildcards):
    inp = {
        "lips": [
            f"<results>/lips/{ls}/reconstruction.tsv"
            for ls in config["lips"]["subjects"]
        ]
    }
    if DATASETS:
        inp["rank_summary"] = "<results>/tables/rank_summary.tsv"
        inp["selected"] = "<results>/tables/selected_markers.tsv"
    return inp


def simulated_subject_params(wildcards):
    subj = SUBJECTS[wildcards.subject]
    return {
        "design": subj.simulate,
        "seed": subj.seed,
        "talker_seed": subj.talker_seed,
        "n_sentences": subj.n_sentences,
        "sentence_duration": subj.sentence_duration,
        "format": subj.format,
        "shared_data": str(SHARED_DATA),
    }


def load_inputs(wildcards):
    subj = SUBJECTS[DATASETS[wildcards.dataset].subject]
    if subj.simulate:
        return [f"<results>/virtual/{subj.id}"]
    return subj.recordings + subj.segment_sources


def lip_params(wildcards):
    spec = dict(config["lips"]["subjects"][wildcards.lip_subject])
    spec.pop(
        "optional", None
    )  # whether to skip it without the shared data: not an input
    lips = config["lips"]
    return {
        "subject": spec,
        "n_modes": lips["n_modes"],
        "normalisation": lips["normalisation"],
        "train_frames": lips["train_frames"],
        "test_frames": lips["test_frames"],
        "noise_var": lips["noise_var"],
        "noise_var_sweep": lips["noise_var_sweep"],
        "model_extent": lips["model_extent"],
        "E": lips["E"],
        "nu": lips["nu"],
    }


LIP_SUBJECTS = list(config["lips"]["subjects"])  # after the skipped ones are dropped


def lip_wc(ls):
    """The wildcards of a job of lip subject ``ls`` alone."""
    return SimpleNamespace(lip_subject=ls)


def lip_inputs_lists(ls):
    """A lip subject's own inputs, as lists (run_per_dataset's per-dataset inputs)."""
    inp = lip_inputs(lip_wc(ls))
    return {
        # params are not paths to Snakemake: <results> resolved here
        "tracks": [workflow.pathvars.apply(t) for t in inp["tracks"]],
        "mesh": [inp["mesh"]] if "mesh" in inp else [],
    }


def lip_inputs(wildcards):
    spec = config["lips"]["subjects"][wildcards.lip_subject]
    if spec["source"] == "grid":
        return {
            "tracks": [
                str(SHARED_DATA / "grid" / f"grid_{c}.trc")
                for c in spec.get("clips", ["pwij3p", "swwp2s"])
            ],
            "mesh": str(SHARED_DATA / "mesh" / "canonical_face_model.obj"),
        }
    return {"tracks": [f"<results>/lips/{wildcards.lip_subject}/tracks.trc"]}


# ---- virtual talkers (sweep over the generator's talker seed) ----
from facemotion.study.sheet import Dataset, Subject, n_heldout

TALKERS = []
with exit_on_error():
    for _i in range(config["virtual_talkers"]["n_talkers"]):
        _sid = f"V{_i + 1:02d}"
        _n = config["virtual_talkers"]["n_sentences"]
        _design = config["virtual_talkers"]["design"]
        if _design not in ("S1", "S2a", "S2b", "S"):
            raise InputError(
                f"setting virtual_talkers.design: unknown design {_design!r}"
            )
        _head = [f"H{j}" for j in range(1, 7)]
        SUBJECTS[_sid] = Subject(
            id=_sid,
            recordings=[
                f"{RESULTS}/virtual/{_sid}/{_sid}_s{j + 1:02d}.c3d" for j in range(_n)
            ],
            format="c3d",
            head_markers=_head,
            exclude_markers=_head,
            simulate=_design,
            seed=1000 + _i,
            talker_seed=_i + 1,
            n_sentences=_n,
            # the S1 design loses marker 13 after each sentence's first frame (synth.py)
            copy_markers=[("13", "11")] if _design == "S1" else [],
        )
        _held = n_heldout(_n, config["heldout_fraction"])
        DATASETS[_sid] = Dataset(
            _sid, _sid, _sid, list(range(_n - _held)), list(range(_n - _held, _n))
        )
        TALKERS.append(_sid)

    if not DATASETS:
        raise InputError(
            "no datasets: set default_datasets: true, define config.datasets or "
            "virtual_talkers"
        )
EVAL_DATASETS = [d for d, ds in DATASETS.items() if ds.heldout]
# the datasets grouped by subject, in the sheet's order: the order load_dataset loads them in
LOAD_ORDER = [d for s in SUBJECTS for d, ds in DATASETS.items() if ds.subject == s]
# load_dataset's worker processes: one per subject, at most 4 (Snakemake caps them at --cores)
LOAD_THREADS = max(1, min(4, len({DATASETS[d].subject for d in LOAD_ORDER})))
# the virtual subjects the datasets load (simulate_subject writes them all in one job)
VIRTUAL = [
    s
    for s in dict.fromkeys(DATASETS[d].subject for d in LOAD_ORDER)
    if SUBJECTS[s].simulate
]


# ---- every setting against the data's marker and sentence counts (parse time) ----
from facemotion.io.registry import read_labels
from facemotion.study.sweeps import expand_grid
from facemotion.virtual.dense import DENSE_DESIGNS, dense_layout
from facemotion.virtual.talker import marker_layout


def _file_labels(subj):
    """A subject's marker labels, known at parse time (reads one file's header)."""
    if subj.simulate in DENSE_DESIGNS:
        return dense_layout(subj.simulate)
    if subj.simulate:
        return marker_layout(design=subj.simulate)[0]
    return read_labels(
        subj.recordings[0], subj.format, subject_prefix=subj.subject_prefix
    )


def _lip_frames(ls, spec):
    if spec["source"] == "grid":
        # the header's count (the job reads every frame)
        from facemotion.io.trc import trc_frame_count

        tracks = lip_inputs(SimpleNamespace(lip_subject=ls))["tracks"]
        return sum(trc_frame_count(t) for t in tracks)
    return spec.get("frames", 150)


SWEEPS = {}
with exit_on_error():
    _labels = {
        s: _file_labels(SUBJECTS[s]) for s in {ds.subject for ds in DATASETS.values()}
    }
    COUNTS = {
        d: data_counts(SUBJECTS[ds.subject], ds, _labels[ds.subject])
        for d, ds in DATASETS.items()
    }
    check_settings(config, COUNTS)
    for _name, _spec in config["sweeps"].items():
        check_sweep(_name, _spec, COUNTS)
        _dsets = _spec.get("datasets") or list(DATASETS)
        SWEEPS[_name] = {
            "datasets": _dsets,
            "points": {p["name"]: p for p in expand_grid(_spec)},
        }
    check_lip_frames(
        config,
        {ls: _lip_frames(ls, spec) for ls, spec in config["lips"]["subjects"].items()},
    )


def sweep_point_files(wildcards):
    """One table per dataset and point, named by the point's values (sweeps.point_name)."""
    sw = SWEEPS[wildcards.sweep]
    return [
        f"<results>/sweeps/{wildcards.sweep}/{d}/{name}.tsv"
        for d in sw["datasets"]
        for name in sw["points"]
    ]


def sweep_outputs():
    out = [f"<results>/tables/sweep_{name}.tsv" for name in SWEEPS]
    if TALKERS:
        out.append("<results>/tables/talkers.tsv")
    return out


# ---- the papers against this study (compare.smk) ----
# Datasets whose labels are Lucero & Munhall's (Table I): the comparison reads their outputs.
PAPER_LABELS = ("S1", "S2a", "S2b", "S2a*", "S2b*")
COMPARISON_DATASETS = {
    ds.label: d for d, ds in DATASETS.items() if ds.label in PAPER_LABELS
}
_lip_virtual = [
    ls for ls, spec in config["lips"]["subjects"].items() if spec["source"] == "virtual"
]
COMPARISON_LIP_SUBJECT = (
    "virtual"
    if "virtual" in _lip_virtual
    else (_lip_virtual[0] if _lip_virtual else None)
)


def comparison_outputs():
    if not COMPARISON_DATASETS and COMPARISON_LIP_SUBJECT is None:
        return []
    return ["<results>/tables/paper_comparison.tsv"]


def comparison_inputs(wildcards):
    """Named inputs: the tables, then per paper dataset its R values, stability, error curve,
    trajectory and (when k = 10 is fitted) coefficients."""
    inp = {}
    if DATASETS:
        inp["selected"] = "<results>/tables/selected_markers.tsv"
        inp["rank_summary"] = "<results>/tables/rank_summary.tsv"
    for label, d in COMPARISON_DATASETS.items():
        inp[f"r_values__{d}"] = f"<results>/{d}/qr/r_values.tsv"
        inp[f"stability__{d}"] = f"<results>/{d}/qr/stability.tsv"
        if d in EVAL_DATASETS:
            inp[f"curve__{d}"] = f"<results>/{d}/eval/error_curve.tsv"
            inp[f"trajectory__{d}"] = f"<results>/{d}/eval/trajectory_errors.tsv"
        if 10 in config["fit"]["k"]:
            inp[f"coefficients__{d}"] = f"<results>/{d}/fit/coefficients_k10.tsv"
    if COMPARISON_LIP_SUBJECT is not None:
        ls = COMPARISON_LIP_SUBJECT
        inp["lip_reconstruction"] = f"<results>/lips/{ls}/reconstruction.tsv"
        inp["lip_counts"] = f"<results>/lips/{ls}/model_counts.tsv"
    return inp
