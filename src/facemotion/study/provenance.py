"""Provenance sidecars and deterministic, atomic writing of tables and figures.

Every table (TSV) and figure (PNG, plus PDF or SVG when the ``figures.formats`` setting asks
for them) the study writes gets a ``<stem>.meta.json``
sidecar: the output's schema id and version, the package version, the git commit of the code,
the configuration values used and checksums of the inputs and of the outputs themselves.
Nothing in a sidecar depends on the clock or on the machine, so a rerun with the same inputs
reproduces every byte.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import subprocess
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # tables come from pandas; this module itself does not need it
    import pandas as pd
from facemotion._version import __version__
from facemotion.errors import InputError
from facemotion.io.atomic import atomic_write_bytes
from facemotion.plots.save import figure_bytes
from facemotion.study.outputs import sidecar

# Output schemas: id -> (version, required columns). Tables are checked against their schema
# before they are written, so a contract break fails loudly instead of shipping a wrong table.
TABLE_SCHEMAS: dict[str, tuple[str, tuple[str, ...]]] = {
    "gap_report": ("2", ("marker", "frames", "missing_frames", "missing_fraction",
                         "longest_gap_frames", "n_gaps", "outlier_frames", "filled_frames",
                         "fill_method")),
    "sentences": ("2", ("sentence", "file", "role", "frames", "duration_s",
                        "head_fit_rms_mm", "head_fit_max_mm", "units", "units_from",
                        "units_conflict", "face_spread_mm", "shape_rms_mm",
                        "outlier_samples")),
    "r_values": ("2", ("order", "marker", "r", "r_rms", "r_rms_frame", "r_normalised",
                       "r_normalisation")),
    "rank": ("3", ("tolerance_mm", "tolerance_from", "r_normalisation", "epsilon_rank",
                   "r22_norm_at_rank_mm", "diagonal_count", "redundant_markers")),
    "redundancy": ("1", ("marker", "explained_by", "coefficient", "residual_rms_mm",
                         "start_s", "end_s")),
    "sentence_sweep": ("1", ("n_sentences", "order", "marker", "r_rms")),
    "stability": ("1", ()),
    "optimality": ("1", ("k",)),
    "marker_set": ("1", ("marker", "role", "order", "expected_error_mm", "error_low_mm",
                         "error_high_mm")),
    "design_consensus": ("1", ("marker", "role", "order", "expected_error_mm", "error_low_mm",
                               "error_high_mm", "placed_by_subjects", "subject_labels")),
    "design_consensus_subjects": ("1", ("subject", "dataset", "sentences", "own_k",
                                        "own_selected", "own_expected_error_mm",
                                        "consensus_error_mm")),
    "coefficients": ("1", ("main_marker",)),
    "error_curve": ("2", ("k", "mean_abs_error_mm", "rel_error_per_marker", "rel_error_pooled",
                          "median_abs_error_mm",
                          "max_abs_error_mm")),
    "trajectory_errors": ("2", ("marker", "sentence", "k", "in_basis", "axis",
                                "max_abs_error_mm")),
    "selected_markers": ("1", ("order",)),
    "lip_modes": ("1", ("mode", "variance", "cumulative_fraction")),
    "lip_fit_residuals": ("1", ("frame",)),
    "lip_reconstruction": ("3", ("lip_subject", "view", "point_set", "covariance", "noise",
                                 "estimator_reading", "noise_var_model_units2",
                                 "n_observed_dof", "n_evaluated_dof",
                                 "mse_per_dof_model_units2", "mse_per_dof_mm2",
                                 "chosen_reading", "paper_definition",
                                 "paper_mse_per_dof_model_units2")),
    "lip_table1_seed": ("1", ("lip_subject", "seed", "estimator_reading", "chosen_reading",
                              "view", "full_over_modes", "modes_better")),
    "lip_table1_seeds": ("1", ("lip_subject", "seed", "estimator_reading", "chosen_reading",
                               "view", "full_over_modes", "modes_better")),
    "lip_model_counts": ("1", ("lip_subject", "quantity", "paper_value", "our_value", "unit",
                               "paper_place")),
    "summary": ("1", ()),
    "paper_comparison": ("2", ("row", "paper", "where", "statement", "class", "paper_value",
                               "our_value", "measure", "output", "verdict", "rule")),
    "manifest": ("1", ("path", "sha256", "schema_id", "schema_version", "sidecar")),
}


FIGURE_SCHEMA_VERSION = "2"


_INPUT_DIGESTS: dict[tuple, str] = {}  # (device, inode, size, mtime, ctime) -> sha256


def sha256_file(path: str | os.PathLike, *, job_input: bool = False) -> str:
    """SHA-256 of a file's bytes. A job's input (``job_input``: a file the job reads and
    never writes, e.g. a 20 MB displacement file that each of its sidecars names) is hashed
    once per process while its device, inode, size and times stay the same."""
    key = None
    if job_input:
        st = os.stat(path)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
        if key in _INPUT_DIGESTS:
            return _INPUT_DIGESTS[key]
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    if key is not None:
        _INPUT_DIGESTS[key] = h.hexdigest()
    return h.hexdigest()


@lru_cache(maxsize=1)
def git_commit() -> dict[str, Any]:
    """Commit of the code that is running, and whether its tree had uncommitted changes."""
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"],
                                capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain", "--", "."],
                               capture_output=True, text=True, check=True).stdout.strip()
        return {"commit": commit, "dirty": bool(dirty)}
    except (OSError, subprocess.CalledProcessError):
        return {"commit": "unknown", "dirty": None}


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)


@dataclass
class Provenance:
    """What produced an output: the step, the settings it used and the inputs it read."""

    step: str
    config: Mapping[str, Any] = field(default_factory=dict)
    inputs: Iterable[str] = ()
    job_outputs: Iterable[str] = ()  # every output the job declares (for the manifest)
    #: how input files are recorded (a file outside the study by the name the study gives
    #: it, so that the sidecar is the same wherever the study runs)
    names: Mapping[str, str] = field(default_factory=dict)

    def sidecar(self, schema_id: str, schema_version: str, outputs: Iterable[str]) -> dict:
        return {
            "schema_id": f"facemotion/{schema_id}",
            "schema_version": schema_version,
            "package": "facemotion",
            "package_version": __version__,
            "git": git_commit(),
            "step": self.step,
            "config": _jsonable(dict(self.config)),
            "inputs": sorted(({"path": self.names.get(p, p),
                               "sha256": sha256_file(p, job_input=True)}
                              for p in set(map(str, self.inputs)) if os.path.isfile(p)),
                             key=lambda e: e["path"]),
            "outputs": [{"path": str(p), "sha256": sha256_file(p)} for p in outputs],
            "job_outputs": sorted(set(map(str, self.job_outputs))),
        }


def sidecar_path(path: str | os.PathLike) -> Path:
    """``results/x/r_values.tsv`` -> ``results/x/r_values.meta.json``."""
    return Path(sidecar(path))


def _write_sidecar(prov: Provenance, schema_id: str, version: str, outputs: list[str],
                   extra: dict | None = None) -> Path:
    side = sidecar_path(outputs[0])
    text = json.dumps({**prov.sidecar(schema_id, version, outputs), **(extra or {})}, indent=2,
                      sort_keys=False)
    atomic_write_bytes(side, (text + "\n").encode())
    return side


def table_bytes(df: pd.DataFrame) -> bytes:
    """The TSV form of a table: fixed float format, no index, Unix newlines."""
    buf = io.StringIO()
    df.to_csv(buf, sep="\t", index=False, float_format="%.9g", lineterminator="\n")
    return buf.getvalue().encode()


def write_table(df: pd.DataFrame, path: str | os.PathLike, schema_id: str,
                prov: Provenance) -> Path:
    """Write a TSV table and its sidecar; returns the sidecar's path."""
    if schema_id not in TABLE_SCHEMAS:
        raise KeyError(f"unknown table schema {schema_id!r}")
    version, required = TABLE_SCHEMAS[schema_id]
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise InputError(f"{path}: table {schema_id!r} lacks required columns {missing}")
    atomic_write_bytes(path, table_bytes(df))
    return _write_sidecar(prov, schema_id, version, [str(path)])


def figure_subject(prov: Provenance) -> str | None:
    """What a per-dataset job's figure shows: the dataset's label (its ``label`` param, e.g.
    "S2a*"), else the dataset or lip subject wildcard; None for an aggregation."""
    wc = prov.config.get("wildcards") or {}
    params = prov.config.get("params") or {}
    if "dataset" in wc:
        return str(params.get("label") or wc["dataset"])
    for key in ("lip_subject", "subject"):
        if key in wc:
            return str(wc[key])
    return None


def save_figure(fig, paths: Iterable[str | os.PathLike], schema_id: str,
                prov: Provenance) -> Path:
    """Save one figure in every format named by ``paths`` (by suffix: png, pdf or svg; the
    rules name the formats of the ``figures.formats`` setting), plus one sidecar.  A figure
    of one dataset is titled with it (``plots.style.name_figure``) and its sidecar records the
    titles."""
    from facemotion.plots.style import figure_titles, name_figure

    paths = [str(p) for p in paths]
    if not paths:
        raise ValueError("save_figure needs at least one path")
    subject = figure_subject(prov)
    if subject:
        name_figure(fig, subject)
    titles = figure_titles(fig)
    for i, p in enumerate(paths):
        atomic_write_bytes(p, figure_bytes(fig, Path(p).suffix.lstrip(".").lower()))
        if i == 0 and len(paths) > 1 and fig.get_layout_engine() is not None:
            # the layout (constrained: several passes over every tick label) is the same for
            # every format: keep the first one's instead of computing it again
            fig.set_layout_engine("none")
    plt = sys.modules.get("matplotlib.pyplot")  # the plots build Figures without pyplot:
    if plt is not None:  # importing it only to close them would cost every job ~0.3 s
        plt.close(fig)
    return _write_sidecar(prov, f"figure/{schema_id}", FIGURE_SCHEMA_VERSION, paths,
                          {"titles": titles})


def write_artifact(path: str | os.PathLike, data: bytes, schema_id: str, prov: Provenance,
                   version: str = "1", also: Iterable[str | os.PathLike] = ()) -> Path:
    """Write any other output (an animation, an npz) with a sidecar; the sidecar also lists
    the files ``also`` (already written by the same job, e.g. the C3D files of a subject)."""
    atomic_write_bytes(path, data)
    return _write_sidecar(prov, schema_id, version, [str(path), *map(str, also)])


def sidecar_for_existing(path: str | os.PathLike, schema_id: str, prov: Provenance,
                         version: str = "1") -> Path:
    """Sidecar for an output that a library wrote itself (already in place)."""
    return _write_sidecar(prov, schema_id, version, [str(path)])
