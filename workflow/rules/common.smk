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
    if "subjects" in _user and "lips" not in _user:
        # your own sheet: keep the built-in virtual lip talker, not the GRID one (shared data)
        _base["lips"]["subjects"] = {
            k: v for k, v in _base["lips"]["subjects"].items() if v["source"] != "grid"
        }
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
for _ls, _spec in config["lips"]["subjects"].items():
    if _spec["source"] == "grid" and not (SHARED_DATA / "grid").is_dir():
        raise InputError(
            f"setting lips.subjects.{_ls}: the GRID clips are read from {SHARED_DATA}/grid, "
            "which does not exist; set shared_data or remove this lip subject"
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
    return out + sweep_outputs()


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
        "normalisation": lips["normalisation"],
        "train_frames": lips["train_frames"],
        "test_frames": lips["test_frames"],
        "noise_var": lips["noise_var"],
        "noise_var_sweep": lips["noise_var_sweep"],
        "model_extent": lips["model_extent"],
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


# ---- virtual talkers (sweep over the generator's talker seed) ----
from facemotion.subjects import Dataset, Subject

TALKERS = []
for _i in range(config["virtual_talkers"]["n_talkers"]):
    _sid = f"V{_i + 1:02d}"
    _n = config["virtual_talkers"]["n_sentences"]
    _design = config["virtual_talkers"]["design"]
    if _design not in ("S1", "S2a", "S2b", "S"):
        raise InputError(f"setting virtual_talkers.design: unknown design {_design!r}")
    _head = [f"H{j}" for j in range(1, 7)]
    SUBJECTS[_sid] = Subject(
        id=_sid,
        recordings=[
            f"results/virtual/{_sid}/{_sid}_s{j + 1:02d}.c3d" for j in range(_n)
        ],
        format="c3d",
        head_markers=_head,
        exclude_markers=_head,
        simulate=_design,
        seed=1000 + _i,
        talker_seed=_i + 1,
        n_sentences=_n,
    )
    _held = max(1, round(config["heldout_fraction"] * _n))
    DATASETS[_sid] = Dataset(
        _sid, _sid, _sid, list(range(_n - _held)), list(range(_n - _held, _n))
    )
    TALKERS.append(_sid)

if not DATASETS:
    raise InputError(
        "no datasets: set default_datasets: true, define config.datasets or virtual_talkers"
    )
EVAL_DATASETS = [d for d, ds in DATASETS.items() if ds.heldout]


# ---- parameter sweeps ----
from facemotion.sweeps import expand_grid


def n_analysed_markers(dataset):
    """Markers in the analysis of a dataset, known at parse time (reads one file's labels)."""
    subj = SUBJECTS[DATASETS[dataset].subject]
    if subj.include_markers:
        labels = subj.include_markers
    elif subj.simulate:
        labels = [str(i) for i in range(1, 58)] + [f"H{j}" for j in range(1, 7)]
    else:
        from facemotion.readers import read_recording

        labels = read_recording(
            subj.recordings[0], subj.format, units=subj.units
        ).labels
    return len([m for m in labels if m not in set(subj.exclude_markers)])


SWEEPS = {}
for _name, _spec in config["sweeps"].items():
    _dsets = _spec.get("datasets") or list(DATASETS)
    for _d in _dsets:
        if _d not in DATASETS:
            raise InputError(f"setting sweeps.{_name}.datasets: unknown dataset {_d!r}")
        _n = n_analysed_markers(_d)
        for _sub, _labels in (_spec.get("marker_subsets") or {}).items():
            _n = min(_n, len(_labels))
        for _k in _spec.get("k", []):
            if _k >= _n:
                raise InputError(
                    f"setting sweeps.{_name}.k: k={_k} must be smaller than the "
                    f"{_n} markers of dataset {_d}"
                )
        for _t in _spec.get("train_sentences", []):
            if _t > len(DATASETS[_d].train):
                raise InputError(
                    f"setting sweeps.{_name}.train_sentences: {_t} exceeds the "
                    f"{len(DATASETS[_d].train)} training sentences of dataset {_d}"
                )
    SWEEPS[_name] = {"datasets": _dsets, "points": expand_grid(_spec)}


def sweep_point_files(wildcards):
    sw = SWEEPS[wildcards.sweep]
    return [
        f"results/sweeps/{wildcards.sweep}/{d}/point_{i:03d}.tsv"
        for d in sw["datasets"]
        for i in range(len(sw["points"]))
    ]


def sweep_outputs():
    out = [f"results/tables/sweep_{name}.tsv" for name in SWEEPS]
    if TALKERS:
        out.append("results/tables/talkers.tsv")
    return out
