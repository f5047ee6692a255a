"""Parse-time checks of the settings against the data: never clamp a setting, refuse it.

The workflow (``workflow/rules/common.smk``) knows, before any job runs, how many markers each
dataset analyses and how many training and held-out sentences it has. Every setting that
counts markers or sentences is checked against those numbers here, so that a value the data
cannot honour stops the run at once with one line naming the setting, instead of being
quietly reduced at run time (``animation.k: 100`` drawn with 56 markers) or failing an hour
later.

:func:`exit_on_error` turns an InputError (or a schema violation) raised while the workflow
is parsed into one line on stderr, ``facemotion: <message>``, and exit status 1, so that the
message is the first thing the user sees.
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass

from facemotion.errors import InputError


@dataclass(frozen=True)
class DataCounts:
    """What a dataset holds, as far as the settings are concerned."""

    markers: int      # markers analysed (after include/exclude)
    train: int        # training sentences
    heldout: int      # held-out sentences
    labels: tuple[str, ...] = ()  # the markers analysed


def _fail(setting: str, message: str) -> None:
    raise InputError(f"setting {setting}: {message}")


def check_settings(config: dict, counts: dict[str, DataCounts]) -> None:
    """InputError naming the first setting that the datasets in ``counts`` cannot honour."""
    qr, fit, ev, anim = config["qr"], config["fit"], config["eval"], config["animation"]
    checks = config.get("checks", {})
    if config.get("neutral") == "mean_first_10" and checks.get("min_take_frames", 10) < 10:
        _fail("checks.min_take_frames", f"{checks['min_take_frames']} is below the 10 frames "
              "that neutral: mean_first_10 averages")
    if ev.get("selection_resamples", 0) > ev.get("interval_resamples", 0):
        _fail("eval.selection_resamples", f"{ev['selection_resamples']} is more than the "
              f"{ev['interval_resamples']} resamples of eval.interval_resamples it is drawn from")
    for k in fit["k"]:
        if k < fit["orthogonal_maps"]:
            _fail("fit.orthogonal_maps", f"{fit['orthogonal_maps']} maps of the first pivots' "
                  f"directions but fit.k has k = {k}; the maps show at most k pivots")
    k_max = qr.get("k_max")
    if k_max is not None:
        used = [("fit.k", k) for k in fit["k"]] + [("eval.trajectory_k", ev["trajectory_k"])]
        if anim["enabled"]:
            used.append(("animation.k", anim["k"]))
        for setting, k in used:
            if k > k_max:
                _fail(setting, f"k = {k} exceeds qr.k_max = {k_max} (the error curves and, "
                      "on the randomized route, the ranking stop there)")
    elif qr.get("method") == "randomized":
        _fail("qr.k_max", "the randomized route (qr.method: randomized) needs k_max, the "
              "number of pivots to choose")
    for d, c in counts.items():
        n = c.markers
        of = f"dataset {d}, which analyses {n} markers"
        if k_max is not None and not k_max < n:
            _fail("qr.k_max", f"{k_max} must be fewer than the markers of {of}")
        for k in fit["k"]:
            if not k < n:
                _fail("fit.k", f"k = {k} main markers must be fewer than the markers of {of}")
        if qr["sweep_pivots"] > n:
            _fail("qr.sweep_pivots", f"{qr['sweep_pivots']} pivots exceed the markers of {of}")
        for k in qr["agreement_k"]:
            if k > n:
                _fail("qr.agreement_k", f"k = {k} exceeds the markers of {of}")
        if not qr["optimality_k_max"] < n:
            _fail("qr.optimality_k_max", f"{qr['optimality_k_max']} must be fewer than the "
                  f"markers of {of}")
        if c.heldout == 0:
            continue
        held = f"dataset {d}, which holds out {c.heldout} sentence(s)"
        if not ev["trajectory_k"] < n:
            _fail("eval.trajectory_k", f"k = {ev['trajectory_k']} main markers must be fewer "
                  f"than the markers of {of}")
        if ev["trajectory_sentence"] > c.heldout:
            _fail("eval.trajectory_sentence", f"held-out sentence {ev['trajectory_sentence']} "
                  f"does not exist in {held}")
        if anim["enabled"]:
            if not anim["k"] < n:
                _fail("animation.k", f"k = {anim['k']} main markers must be fewer than the "
                      f"markers of {of}")
            if anim["sentences"] > c.heldout:
                _fail("animation.sentences", f"{anim['sentences']} sentences to animate but "
                      f"{held}")


def check_sweep(name: str, spec: dict, counts: dict[str, DataCounts]) -> None:
    """A sweep's k and train_sentences against each of its datasets."""
    for d in spec.get("datasets") or list(counts):
        if d not in counts:
            _fail(f"sweeps.{name}.datasets", f"unknown dataset {d!r}")
        n = counts[d].markers
        for sub, labels in (spec.get("marker_subsets") or {}).items():
            absent = [m for m in labels if m not in set(counts[d].labels)]
            if counts[d].labels and absent:
                _fail(f"sweeps.{name}.marker_subsets.{sub}", f"marker(s) "
                      f"{', '.join(absent[:5])} are not analysed in dataset {d}")
            n = min(n, len(labels))
        for k in spec.get("k", []):
            if k >= n:
                _fail(f"sweeps.{name}.k", f"k={k} must be smaller than the {n} markers of "
                      f"dataset {d}")
        for t in spec.get("train_sentences", []):
            if t > counts[d].train:
                _fail(f"sweeps.{name}.train_sentences", f"{t} exceeds the {counts[d].train} "
                      f"training sentences of dataset {d}")


def check_lip_frames(config: dict, frames: dict[str, int]) -> None:
    """lips.train_frames / test_frames / n_modes against each lip subject's frame count."""
    from facemotion.study.sheet import parse_sentences

    lips = config["lips"]
    for ls, n in frames.items():
        train = parse_sentences(lips["train_frames"], n, f"lips.train_frames (lip subject "
                                f"{ls}, {n} frames)")
        test = parse_sentences(lips["test_frames"], n, f"lips.test_frames (lip subject {ls}, "
                               f"{n} frames)")
        if set(train) & set(test):
            _fail("lips.test_frames", f"frames {sorted(set(train) & set(test))[:5]} are also "
                  "training frames")
        if lips["n_modes"] >= len(train):
            _fail("lips.n_modes", f"{lips['n_modes']} modes need more than {len(train)} "
                  f"training frames (lip subject {ls})")


def _load_schema(schema_path) -> dict:
    import yaml

    with open(schema_path) as fh:
        return yaml.safe_load(fh)


def sheet_schema(schema_path) -> dict:
    """The subject sheet's schema, with the lists the package holds filled in: the formats
    (:data:`facemotion.io.registry.FORMATS`), the units and the virtual designs."""
    from facemotion.io.base import UNITS
    from facemotion.io.registry import FORMAT_NAMES
    from facemotion.virtual.designs import DESIGN_NAMES

    schema = _load_schema(schema_path)
    props = schema["properties"]
    props["format"]["enum"] = list(FORMAT_NAMES)
    props["units"]["enum"] = ["", *UNITS]
    props["simulate"]["enum"] = ["", *DESIGN_NAMES]
    return schema


#: The schema's pattern of every name that becomes part of a path (study, dataset, sweep, ...).
ID_PATTERN = "^[A-Za-z0-9][A-Za-z0-9_.-]*$"


def _best_error(data, schema: dict):
    import jsonschema

    return jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(schema).iter_errors(data))


def _refuse_non_finite(value, where: str = "") -> None:
    """NaN and infinity in any setting are errors: NaN passes every minimum and maximum of
    the schema (each comparison is false), so a NaN tolerance would give an epsilon-rank."""
    if isinstance(value, float) and not math.isfinite(value):
        raise InputError(f"setting {where or '(top level)'}: {value} is not a finite number")
    if isinstance(value, dict):
        for k, v in value.items():
            _refuse_non_finite(v, f"{where}.{k}" if where else str(k))
    elif isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _refuse_non_finite(v, f"{where}.{i}")


def validate_config(config: dict, schema_path) -> None:
    """Snakemake's schema validation (which also fills in the defaults), with a failure as an
    InputError of one line naming the setting."""
    from snakemake.utils import validate

    _refuse_non_finite(config)
    try:
        validate(config, str(schema_path))
    except Exception as exc:  # snakemake's WorkflowError, several lines long
        err = _best_error(config, _load_schema(schema_path))
        if err is None:
            raise InputError(f"settings: {str(exc).strip().splitlines()[0]}") from None
        where = ".".join(str(p) for p in err.absolute_path) or "(top level)"
        message = err.message.splitlines()[0][:200]
        if err.validator == "pattern" and err.validator_value == ID_PATTERN:
            message = (f"{str(err.instance)[:80]!r} is not a name of letters, digits, '_', '.' "
                       "and '-' starting with a letter or digit (it becomes part of output "
                       "paths)")
        raise InputError(f"setting {where}: {message}") from None


def validate_sheet(sheet_path, schema_path) -> None:
    """The subject sheet against its schema, row by row; one line naming row and column."""
    from facemotion.study.sheet import read_sheet_table

    table = read_sheet_table(sheet_path)
    schema = sheet_schema(schema_path)
    for i, row in enumerate(table.to_dict("records")):
        err = _best_error(row, schema)
        if err is not None:
            col = ".".join(str(p) for p in err.absolute_path) or "(row)"
            raise InputError(f"subject sheet {sheet_path}, row {i + 2}, column {col}: "
                             f"{err.message.splitlines()[0][:200]}")


def data_counts(subject, dataset, labels: list[str]) -> DataCounts:
    """Markers a dataset analyses (of the file's ``labels``) and its sentence counts; a marker
    that the sheet names and the data lacks is an error naming the sheet's column."""
    for col in ("head_markers", "exclude_markers", "include_markers"):
        absent = [m for m in getattr(subject, col) if m not in set(labels)]
        if absent:
            raise InputError(f"subject {subject.id}: {col} names marker(s) "
                             f"{', '.join(absent[:5])} that {subject.recordings[0]} does not "
                             f"have (it has {len(labels)} markers)")
    keep = [m for m in (subject.include_markers or labels)
            if m not in set(subject.exclude_markers)]
    if len(keep) < 2:
        raise InputError(f"subject {subject.id}: fewer than 2 markers left after the sheet's "
                         "include_markers/exclude_markers")
    return DataCounts(markers=len(keep), train=len(dataset.train),
                      heldout=len(dataset.heldout), labels=tuple(keep))


@contextlib.contextmanager
def exit_on_error() -> Iterator[None]:
    """Run parse-time code; an InputError ends the run with one line on stderr and exit 1."""
    try:
        yield
    except InputError as exc:
        print(f"facemotion: {exc}", file=sys.stderr, flush=True)
        raise SystemExit(1) from None


def merge_default_config(user: dict, default: dict) -> dict:
    """The config of a run without ``--configfile``: the default study's, overridden by the
    ``--config`` values in ``user``.

    ``--config subjects=SHEET`` alone runs the default settings on the user's sheet, one
    dataset per subject (the default config's paper datasets only make sense for its own
    sheet), as the study named after the sheet, keeping the built-in virtual lip talker but not
    the GRID one (it reads the shared data).
    """
    base = dict(default)
    if "subjects" in user:
        base["study"] = None  # named after the sheet, unless --config study=NAME
        if "datasets" not in user:
            base.pop("datasets", None)
            base["default_datasets"] = True
        if "lips" not in user:
            lips = dict(base["lips"])
            lips["subjects"] = {k: v for k, v in lips["subjects"].items()
                                if v["source"] != "grid"}
            base["lips"] = lips
    base.update(user)
    return base


def limits_from_config(gaps: dict, checks: dict):
    """The loading checks' limits from the ``gaps`` and ``checks`` settings."""
    from facemotion.ingest.validation import Limits

    groups = {"gaps": ("max_distance_mm", "max_speed_mm_s", "outliers"),
              "checks": ("min_take_frames", "face_spread_mm", "rate_hz", "max_shape_rms_mm")}
    names = {f: f"setting {group}.{f}" for group, fields in groups.items() for f in fields}
    return Limits(max_distance_mm=gaps["max_distance_mm"],
                  max_speed_mm_s=gaps["max_speed_mm_s"], outliers=gaps["outliers"],
                  min_take_frames=checks["min_take_frames"],
                  face_spread_mm=tuple(checks["face_spread_mm"]),
                  rate_hz=tuple(checks["rate_hz"]),
                  max_shape_rms_mm=checks["max_shape_rms_mm"], names=names)


def lip_settings(lips: dict, n_frames: int):
    """The lip model's settings (:class:`facemotion.lips.pipeline.LipSettings`) from the
    ``lips`` settings, for a lip subject of ``n_frames`` frames: the frame selections made
    0-based, noise_var 'auto' read as the probabilistic-PCA choice."""
    from facemotion.lips.pipeline import LipSettings
    from facemotion.study.sheet import parse_sentences

    train = parse_sentences(lips["train_frames"], n_frames, "lips.train_frames")
    test = parse_sentences(lips["test_frames"], n_frames, "lips.test_frames")
    noise_var = "ppca" if lips["noise_var"] == "auto" else lips["noise_var"]
    if isinstance(noise_var, str) and noise_var != "ppca":
        raise InputError(f"setting lips.noise_var: {noise_var!r} is neither a number nor 'auto'")
    extent = lips["model_extent"]
    return LipSettings(train_frames=tuple(train), test_frames=tuple(test),
                       n_modes=lips["n_modes"], noise_var=noise_var, E=lips["E"], nu=lips["nu"],
                       model_extent=None if extent is None else tuple(extent),
                       noise_grid=tuple(lips["noise_var_sweep"]),
                       normalisation=lips["normalisation"])
