# Configuration, subject sheet and datasets; helpers that list each stage's outputs.
import os
from pathlib import Path

import pandas as pd
import yaml
from snakemake.utils import min_version, validate

from facemotion.errors import InputError
from facemotion.subjects import read_subject_sheet, resolve_datasets

min_version("9.0")

REPO = Path(workflow.basedir)
SCRIPTS = REPO / "scripts"

# With no --configfile the default study's config is the base; --config values override it.
# `--config subjects=SHEET` alone runs the default settings on your sheet, one dataset per
# subject (the default config's paper datasets only make sense for its own sheet).
if not workflow.config_settings.configfiles:
    _user = dict(config)
    with open(workflow.source_path("../../config/config.yaml")) as _f:
        _base = yaml.safe_load(_f)
    if "subjects" in _user and "datasets" not in _user:
        _base.pop("datasets", None)
        _base["default_datasets"] = True
    _base.update(_user)
    config.clear()
    config.update(_base)

validate(config, workflow.source_path("../schemas/config.schema.yaml"))


def _resolve(path):
    """A path from the config: as given (relative to the working directory), else the repo's."""
    p = Path(path)
    if p.is_absolute() or p.exists():
        return p
    if (REPO / p).exists():
        return REPO / p
    return p


SHARED_DATA = Path(config["shared_data"] or (REPO.parent / "shared" / "data"))
SHEET = _resolve(config["subjects"])
SUBJECTS = read_subject_sheet(
    SHEET, shared_data=SHARED_DATA, virtual_dir="results/virtual"
)
validate(
    pd.read_csv(SHEET, sep="\t", dtype=str, keep_default_na=False, comment="#"),
    workflow.source_path("../schemas/subjects.schema.yaml"),
)
DATASETS = resolve_datasets(
    SUBJECTS,
    config["datasets"],
    heldout_fraction=config["heldout_fraction"],
    default_per_subject=config["default_datasets"],
)
if not DATASETS:
    raise InputError(
        "no datasets: set default_datasets: true or define config.datasets"
    )
EVAL_DATASETS = [d for d, ds in DATASETS.items() if ds.heldout]


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
        "train": [i + 1 for i in ds.train],
        "heldout": [i + 1 for i in ds.heldout],
        "sentence_names": subj.sentence_names,
    }


def fig(path):
    """A figure's files: PNG for looking, PDF for papers."""
    return [f"{path}.png", f"{path}.pdf"]


def meta(path):
    return f"{path}.meta.json"


def all_outputs():
    out = []
    for d in DATASETS:
        base = f"results/{d}"
        out += [f"{base}/data/displacements.npz", f"{base}/data/gap_report.tsv"]
        out += [f"{base}/qr/r_values.tsv", f"{base}/qr/rank.tsv"]
        out += [f"{base}/qr/redundancy.tsv", f"{base}/qr/stability.tsv"]
        out += [f"{base}/qr/optimality.tsv"]
        out += [f"{base}/fit/coefficients_k{k}.tsv" for k in config["fit"]["k"]]
    for d in EVAL_DATASETS:
        out += [f"results/{d}/eval/error_curve.tsv"]
        if config["animation"]["enabled"]:
            out += [f"results/{d}/anim/heldout_still.png"]
    out += ["results/tables/selected_markers.tsv", "results/figures/r_values.png"]
    if EVAL_DATASETS:
        out += ["results/figures/error_curves.png"]
    for ls in config["lips"]["subjects"]:
        out += [f"results/lips/{ls}/reconstruction.tsv"]
    return out


def final_outputs():
    return all_outputs() + ["results/manifest.tsv"]


def simulated_subject_params(wildcards):
    subj = SUBJECTS[wildcards.subject]
    return {
        "design": subj.simulate,
        "seed": subj.seed,
        "talker_seed": subj.talker_seed,
        "n_sentences": subj.n_sentences,
        "sentence_duration": subj.sentence_duration,
    }


def load_inputs(wildcards):
    subj = SUBJECTS[DATASETS[wildcards.dataset].subject]
    if subj.simulate:
        return [f"results/virtual/{subj.id}"]
    return subj.recordings


def lip_params(wildcards):
    spec = dict(config["lips"]["subjects"][wildcards.lip_subject])
    lips = config["lips"]
    return {
        "subject": spec,
        "n_modes": lips["n_modes"],
        "train_frames": lips["train_frames"],
        "test_frames": lips["test_frames"],
        "noise_var": lips["noise_var"],
        "noise_var_sweep": lips["noise_var_sweep"],
        "E": lips["E"],
        "nu": lips["nu"],
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
    return {"tracks": [f"results/lips/{wildcards.lip_subject}/tracks.trc"]}
