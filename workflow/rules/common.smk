# Configuration, subject sheet and datasets, checked at parse time; each rule's outputs.
import os
import re
import sys
from pathlib import Path
from types import SimpleNamespace

import yaml
from snakemake.utils import min_version

from facemotion.errors import InputError
from facemotion.ingest.scatter import plan as scatter_plan
from facemotion.io.registry import read_labels
from facemotion.io.trc import trc_frame_count
from facemotion.papers.lucero_munhall import TABLE_I
from facemotion.study.invocation import (
    ParseGuard,
    invocation_dir,
    remember_invocation,
    resolve_path,
    same_study_command,
    sample_benchmarks_every,
)
from facemotion.study.outputs import (
    artifact,
    check_inside_study,
    figure_files,
    sidecar,
    table,
    tables,
)
from facemotion.study.outputs import figure as _figure
from facemotion.study.settings import (
    check_lip_frames,
    check_settings,
    check_sweep,
    data_counts,
    exit_on_error,
    merge_default_config,
    validate_config,
    validate_sheet,
)
from facemotion.study.fingerprint import FingerprintCache, fingerprint
from facemotion.study.sheet import (
    consensus_datasets,
    consensus_params,
    dataset_params,
    read_subject_sheet,
    recorded_names,
    resolve_datasets,
    simulation_params,
    virtual_talkers,
)
from facemotion.study.summary import closing_message, study_name
from facemotion.study.sweeps import expand_grid
from facemotion.virtual.dense import dense_layout
from facemotion.virtual.designs import DESIGNS
from facemotion.virtual.talker import marker_layout

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
_OWN_SHEET = "subjects" in config  # from --config, a config file or a host workflow
# the lip subjects are the user's when a config file or --config names them, else the
# default study's (the built-in virtual lip talker)
_OWN_LIPS = "lips" in config or bool(workflow.config_settings.configfiles)
if not workflow.config_settings.configfiles:
    with open(workflow.source_path("../../config/config.yaml")) as _f:
        _merged = merge_default_config(dict(config), yaml.safe_load(_f))
    config.clear()
    config.update(_merged)

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
    config["study"] = STUDY  # the report's description names it


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
    # the sweep over virtual talkers: subjects V01, V02, ... and one dataset each
    _vt = config["virtual_talkers"]
    _talker_subjects, _talker_datasets = virtual_talkers(
        _vt["n_talkers"],
        _vt["design"],
        _vt["n_sentences"],
        config["heldout_fraction"],
        f"{RESULTS}/virtual",
    )
    SUBJECTS.update(_talker_subjects)
    DATASETS.update(_talker_datasets)
    TALKERS = list(_talker_datasets)
    if not DATASETS:
        raise InputError(
            "no datasets: set default_datasets: true, define config.datasets or "
            "virtual_talkers"
        )


# Inputs outside the results are named as the study records them (relative to the study
# root, the sheet's folder or the shared data), so outputs do not depend on where it runs.
RECORDED = recorded_names(SUBJECTS, Path.cwd(), SHEET.parent, SHARED_DATA)
# Reruns follow content: each dataset's recordings and segmentation files by their SHA-256
# (a rule param, so Snakemake's params trigger reruns loading when a file's content changes,
# whatever its modification time); digests cached by file identity and times.
_DIGESTS = FingerprintCache(f"{RESULTS}/.cache/input_digests.json")
with exit_on_error():
    FINGERPRINTS = {
        d: fingerprint(
            SUBJECTS[ds.subject].recordings + SUBJECTS[ds.subject].segment_sources,
            _DIGESTS,
            RECORDED,
        )
        for d, ds in DATASETS.items()
        if not SUBJECTS[ds.subject].simulate
    }
for _path, _old, _new in _DIGESTS.changed:
    print(
        f"facemotion: {RECORDED.get(_path, _path)}: content changed since the last run "
        f"(sha256 {_old[:16]} -> {_new[:16]}); what reads it runs again",
        file=sys.stderr,
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


with exit_on_error():
    for _d in DATASETS:
        _m = _dataset_mesh_path(_d)
        if _m is not None and not Path(_m).is_file():
            raise InputError(f"setting datasets.{_d}.mesh: {_m} is not a file")

EVAL_DATASETS = [d for d, ds in DATASETS.items() if ds.heldout]
# the virtual subjects the datasets read (one simulate_subject job each)
VIRTUAL = [
    s
    for s in dict.fromkeys(ds.subject for ds in DATASETS.values())
    if SUBJECTS[s].simulate
]
LIP_SUBJECTS = list(config["lips"]["subjects"])  # after the skipped ones are dropped
# The marker-set design needs at least two sentences (one to train, one to measure the
# held-out error); a dataset of one sentence (a single GRID clip) has none.
DESIGN_DATASETS = {
    d: ds for d, ds in DATASETS.items() if len(ds.train) + len(ds.heldout) >= 2
}


def _choice(names):
    """A wildcard that matches exactly one of ``names`` (never a folder such as tables/)."""
    return "|".join(re.escape(n) for n in names) if names else "(?!)"


wildcard_constraints:
    dataset=_choice(DATASETS),
    subject=_choice(VIRTUAL),
    lip_subject=_choice(LIP_SUBJECTS),
    k=r"\d+",


# ---- every setting against the data's marker and sentence counts (parse time) ----
def _file_labels(subj):
    """A subject's marker labels, known at parse time (reads one file's header)."""
    if subj.simulate and DESIGNS[subj.simulate].dense:
        return dense_layout(subj.simulate)
    if subj.simulate:
        return marker_layout(design=subj.simulate)[0]
    return read_labels(
        subj.recordings[0], subj.format, subject_prefix=subj.subject_prefix
    )


def lip_inputs(wildcards):
    """A lip subject's tracks (and, for GRID, the face mesh its lip mesh is cut from)."""
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


def _lip_frames(ls, spec):
    if spec["source"] == "grid":
        # the header's count (the job reads every frame)
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
    # the cross-subject consensus: subject -> the dataset it contributes
    CONSENSUS = consensus_datasets(
        SUBJECTS, DESIGN_DATASETS, config["eval"]["consensus"], _labels
    )

# Datasets whose labels are Lucero & Munhall's (Table I): the comparison reads their outputs.
COMPARISON_DATASETS = {ds.label: d for d, ds in DATASETS.items() if ds.label in TABLE_I}
_lip_virtual = [
    ls for ls, spec in config["lips"]["subjects"].items() if spec["source"] == "virtual"
]
COMPARISON_LIP_SUBJECT = (
    "virtual"
    if "virtual" in _lip_virtual
    else (_lip_virtual[0] if _lip_virtual else None)
)
# virtual lip subject -> the seeds its Table 1 is run on (one job each; default: its seed)
LIP_SEEDS = {
    ls: list(
        config["lips"]["subjects"][ls].get(
            "seeds", [config["lips"]["subjects"][ls].get("seed", 0)]
        )
    )
    for ls in _lip_virtual
}


# ---- outputs: each file with its sidecar (and a figure's other formats), by one helper ----
FIGURE_FORMATS = config["figures"]["formats"]


def figure(key, stem, caption=None, category=None, subcategory=None):
    """A figure's outputs (PNG, other formats, sidecar); in the report when it has a caption."""
    wrap = None
    if caption is not None:
        wrap = lambda png: report(
            png,
            caption=f"../report/{caption}.rst",
            category=category,
            subcategory=subcategory,
        )
    return _figure(key, stem, FIGURE_FORMATS, wrap)


def reported_table(key, path, caption, category, subcategory=None):
    """A table with its sidecar, shown in the report."""
    out = table(key, path)
    out[key] = report(
        path,
        caption=f"../report/{caption}.rst",
        category=category,
        subcategory=subcategory,
    )
    return out


def data(wildcards):
    """A dataset's displacements and its sentences table (every analysis reads both)."""
    d = f"<results>/{wildcards.dataset}/data"
    return {"npz": f"{d}/displacements.npz", "sentences": f"{d}/sentences.tsv"}


def dataset_label(wildcards):
    return DATASETS[wildcards.dataset].label


def per_dataset(pattern, datasets):
    """One path per dataset, in the order of ``datasets`` (an aggregation's inputs)."""
    return [pattern.format(dataset=d) for d in datasets]


def load_files_at(wildcards):
    """Where a dataset's input files lie, by the names the study records them by."""
    subj = SUBJECTS[DATASETS[wildcards.dataset].subject]
    return {RECORDED.get(f, f): f for f in subj.recordings + subj.segment_sources}


def load_inputs(wildcards):
    subj = SUBJECTS[DATASETS[wildcards.dataset].subject]
    if subj.simulate:
        return [f"<results>/virtual/{subj.id}"]
    return subj.recordings + subj.segment_sources


def dataset_mesh(wildcards):
    """The face mesh a dataset's maps are drawn on (setting datasets.<id>.mesh), or none."""
    m = _dataset_mesh_path(wildcards.dataset)
    return [str(m)] if m is not None else []


def dataset_mesh_labels(wildcards):
    spec = (config.get("datasets") or {}).get(wildcards.dataset) or {}
    return spec.get("mesh_labels", "L{i:03d}")


def lip_params(wildcards):
    spec = dict(config["lips"]["subjects"][wildcards.lip_subject])
    spec.pop(
        "optional", None
    )  # whether to skip it without the shared data: not an input
    lips = config["lips"]
    return {
        "subject": spec,
        **{k: lips[k] for k in lips if k != "subjects"},
    }


def lip_seed_tables(wildcards):
    """Every virtual lip subject's per-seed Table 1 (the aggregation's inputs)."""
    return [
        f"<results>/lips/{ls}/seeds/table1_seed{seed}.tsv"
        for ls, seeds in LIP_SEEDS.items()
        for seed in seeds
    ]


def sweep_point_files(wildcards):
    """One table per dataset and point, named by the point's values (sweeps.point_name)."""
    sw = SWEEPS[wildcards.sweep]
    return [
        f"<results>/sweeps/{wildcards.sweep}/{d}/{name}.tsv"
        for d in sw["datasets"]
        for name in sw["points"]
    ]


def comparison_inputs(wildcards):
    """Named inputs: the tables across datasets, then per paper dataset its R values,
    stability, error curve, trajectory and (when k = 10 is fitted) coefficients."""
    inp = {
        "selected": "<results>/tables/selected_markers.tsv",
        "rank_summary": "<results>/tables/rank_summary.tsv",
    }
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
        inp["lip_seeds"] = "<results>/lips/table1_seeds.tsv"
    return inp


def summary_inputs(wildcards):
    inp = {
        "lips": [f"<results>/lips/{ls}/reconstruction.tsv" for ls in LIP_SUBJECTS],
        "rank_summary": "<results>/tables/rank_summary.tsv",
        "selected": "<results>/tables/selected_markers.tsv",
        "sentences": per_dataset("<results>/{dataset}/data/sentences.tsv", DATASETS),
    }
    if COMPARISON_DATASETS or COMPARISON_LIP_SUBJECT is not None:
        inp["comparison"] = "<results>/tables/paper_comparison.tsv"
    return inp


def builtin_lip_subjects():
    """In a study of the user's own sheet, the lip subjects that are the built-in virtual lip
    talker (the summary does not present them as the user's results)."""
    if not _OWN_SHEET or _OWN_LIPS:
        return []
    subjects = config["lips"]["subjects"]
    return [ls for ls in LIP_SUBJECTS if subjects[ls].get("source") == "virtual"]


def all_outputs():
    out = []
    for d in DATASETS:
        base = f"<results>/{d}"
        out += [f"{base}/data/displacements.npz", f"{base}/data/gap_report.tsv"]
        out += [f"{base}/qr/r_values.tsv", f"{base}/qr/rank.tsv"]
        out += [f"{base}/qr/redundancy.tsv", f"{base}/qr/stability.tsv"]
        out += [f"{base}/qr/optimality.tsv"]
        out += [f"{base}/fit/coefficients_k{k}.tsv" for k in config["fit"]["k"]]
    for d in DESIGN_DATASETS:
        base = f"<results>/{d}"
        out += [f"{base}/design/markers.tsv", f"{base}/design/marker_set_plot.png"]
    for d in EVAL_DATASETS:
        out += [f"<results>/{d}/eval/error_curve.tsv"]
        if config["animation"]["enabled"]:
            out += [f"<results>/{d}/anim/heldout_still.png"]
    out += ["<results>/tables/selected_markers.tsv", "<results>/figures/r_values.png"]
    if DESIGN_DATASETS:
        out += ["<results>/figures/face_3d.html"]
    if CONSENSUS:
        out += ["<results>/design/consensus.tsv"]
    if EVAL_DATASETS:
        out += ["<results>/figures/error_curves.png"]
    for ls in LIP_SUBJECTS:
        out += [f"<results>/lips/{ls}/reconstruction.tsv"]
    if LIP_SEEDS:
        out += ["<results>/lips/table1_seeds.tsv"]
    out += [f"<results>/tables/sweep_{name}.tsv" for name in SWEEPS]
    if TALKERS:
        out.append("<results>/tables/talkers.tsv")
    if COMPARISON_DATASETS or COMPARISON_LIP_SUBJECT is not None:
        out.append("<results>/tables/paper_comparison.tsv")
    return out + ["<results>/summary.txt"]


def final_outputs():
    return all_outputs() + ["<results>/manifest.tsv"]


def print_closing_summary():
    """After a successful run (onsuccess): the summary, and how to open the report."""
    command = same_study_command(sys.argv, "--report", f"{RESULTS}/report.html")
    text = closing_message(RESULTS, workflow.start_time.timestamp(), command)
    if text:
        print(text, flush=True)


# ---- streamed loading, one job per take (rules/stream.smk) ----
def stream_parts(dataset):
    """The dataset's takes (files), each with its sentences and their roles
    (facemotion.ingest.scatter.plan), in the order they first appear."""
    ds = DATASETS[dataset]
    sentences = SUBJECTS[ds.subject].sentences
    order = list(ds.train) + list(ds.heldout)
    roles = ["train"] * len(ds.train) + ["heldout"] * len(ds.heldout)
    return scatter_plan([sentences[i] for i in order], roles)


def stream_take_ids(dataset):
    """The dataset's takes as t001, t002, ..."""
    return [f"t{i + 1:03d}" for i in range(len(stream_parts(dataset)))]


def stream_params(wildcards):
    """A take's file, sentences and roles, and the dataset's loading settings."""
    part = stream_parts(wildcards.dataset)[int(wildcards.take[1:]) - 1]
    return {
        "ds": dataset_params(SUBJECTS, DATASETS, wildcards.dataset),
        "recording": part.take,
        "sentences": (
            None if part.sentences is None else [s.to_param() for s in part.sentences]
        ),
        "roles": part.roles,
        "positions": part.positions,
    }


def stream_heads(wildcards):
    return expand(
        "<results>/{dataset}/stream/heads/{take}.npz",
        dataset=wildcards.dataset,
        take=stream_take_ids(wildcards.dataset),
    )


def stream_heldout(dataset):
    """The takes with held-out sentences: {take id: the held-out sentences' indices in the
    take's part of A}."""
    ids = stream_take_ids(dataset)
    return {
        ids[k]: part.heldout
        for k, part in enumerate(stream_parts(dataset))
        if part.heldout
    }


def stream_heldout_parts(wildcards):
    """The parts of A of the takes with held-out sentences."""
    return expand(
        "<results>/{dataset}/stream/takes/{take}.npz",
        dataset=wildcards.dataset,
        take=list(stream_heldout(wildcards.dataset)),
    )


def stream_grams(wildcards):
    return expand(
        "<results>/{dataset}/stream/takes/{take}.gram.npz",
        dataset=wildcards.dataset,
        take=stream_take_ids(wildcards.dataset),
    )


# No setting or sheet value places a file outside the study root (checked again by each job
# before it writes, symbolic links included).
with exit_on_error():
    check_inside_study(
        [RESULTS] + [workflow.pathvars.apply(p) for p in final_outputs()]
    )
