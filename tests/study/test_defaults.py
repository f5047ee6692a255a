"""Library defaults that are also settings equal the config schema's defaults.

The schema (workflow/schemas/config.schema.yaml) is the source of truth for the study; a
function of the library whose parameter is a setting has the schema's value as its default, so
``facemotion.load(...)`` and the command line answer as the study does. ``MAPPING`` lists each
setting beside the library objects that hold it; a setting of the schema is either there or in
``WORKFLOW_ONLY`` (no library function has it as a default). A parameter of the library named
like a setting whose default differs from the schema's is either in ``MAPPING`` or in
``NOT_THE_SETTING`` with the reason.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
import inspect
import pkgutil

import pytest
import yaml
from helpers import SCHEMAS

import facemotion

SCHEMA = SCHEMAS / "config.schema.yaml"
NO_DEFAULT = object()


def schema_settings(schema: dict, path: str = "") -> dict[str, dict]:
    """Dotted setting path -> its schema, for every leaf setting; ``*`` stands for a name of
    the user's (a dataset, a lip subject, a sweep)."""
    out = {}
    children = dict(schema.get("properties", {}))
    if isinstance(schema.get("additionalProperties"), dict):
        children["*"] = schema["additionalProperties"]
    for name, sub in children.items():
        p = f"{path}.{name}" if path else name
        if sub.get("type") == "object" or "properties" in sub or (
                isinstance(sub.get("additionalProperties"), dict)
                and sub["additionalProperties"].get("type") == "object"):
            out.update(schema_settings(sub, p))
        else:
            out[p] = sub
    return out


def schema_defaults(schema: dict) -> dict[str, object]:
    return {p: s["default"] for p, s in schema_settings(schema).items() if "default" in s}


def resolve(target: str):
    """``"module:attr.attr"`` -> the object."""
    module, _, qualname = target.partition(":")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def library_default(target: str, param: str | None):
    """The default of parameter ``param`` of the callable (or dataclass field) ``target``, or
    the value of ``target`` itself when ``param`` is None."""
    obj = resolve(target)
    if param is None:
        return obj
    if dataclasses.is_dataclass(obj):
        field = {f.name: f for f in dataclasses.fields(obj)}[param]
        return field.default
    default = inspect.signature(obj).parameters[param].default
    return NO_DEFAULT if default is inspect.Parameter.empty else default


def plain(value):
    """Tuples as lists, recursively (YAML has only lists)."""
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    return value


#: setting -> [(library object, its parameter or None for a constant, {schema value: the
#: library's name for it})]
MAPPING: dict[str, list[tuple]] = {
    "heldout_fraction": [("facemotion.study.sheet:DEFAULT_HELDOUT_FRACTION", None),
                         ("facemotion.study.sheet:resolve_datasets", "heldout_fraction")],
    "neutral": [("facemotion.ingest.loading:load_dataset", "neutral"),
                ("facemotion.ingest.displacements:build_displacements", "neutral")],
    "gaps.max_interp_s": [("facemotion.ingest.loading:load_dataset", "max_interp_s"),
                          ("facemotion.ingest.gaps:fill_gaps", "max_interp_s")],
    "gaps.long_gaps": [("facemotion.ingest.loading:load_dataset", "long_gaps"),
                       ("facemotion.ingest.gaps:fill_gaps", "long_gaps")],
    "gaps.outliers": [("facemotion.ingest.validation:Limits", "outliers")],
    "gaps.max_distance_mm": [("facemotion.ingest.validation:Limits", "max_distance_mm")],
    "gaps.max_speed_mm_s": [("facemotion.ingest.validation:Limits", "max_speed_mm_s")],
    "checks.min_take_frames": [("facemotion.ingest.validation:Limits", "min_take_frames")],
    "checks.face_spread_mm": [("facemotion.ingest.validation:Limits", "face_spread_mm")],
    "checks.rate_hz": [("facemotion.ingest.validation:Limits", "rate_hz")],
    "checks.max_shape_rms_mm": [("facemotion.ingest.validation:Limits", "max_shape_rms_mm")],
    "qr.method": [("facemotion.ranking.routes:rank_markers", "method"),
                  ("facemotion.ranking.routes:rank_for_study", "method"),
                  ("facemotion.ranking.routes:study_route", "method"),
                  ("facemotion.ranking.stability:sentence_sweep", "method"),
                  ("facemotion.regions.selector:MarkerSelector", "method"),
                  ("facemotion.regions.selector:constrained_ranking", "method"),
                  ("facemotion.study.sweeps:evaluate_point", "method")],
    "qr.k_max": [("facemotion.ranking.routes:rank_markers", "k_max"),
                 ("facemotion.ranking.routes:rank_for_study", "k_max"),
                 ("facemotion.regions.prediction:error_curve", "k_max")],
    "qr.tolerances_mm": [("facemotion.cli:DEFAULT_TOLERANCES_MM", None),
                         ("facemotion.plots.rank:plot_r_values", "tolerances")],
    "qr.r_normalisation": [("facemotion.ranking.result:DEFAULT_R_NORMALISATION", None),
                           ("facemotion.ranking.epsilon_rank:epsilon_rank", "normalisation"),
                           ("facemotion.study.sweeps:evaluate_point", "r_normalisation")],
    "eval.target_error_mm": [("facemotion.regions.target:DEFAULT_TARGET_MM", None),
                             ("facemotion.regions.target:k_for_error", "target_mm")],
    "eval.interval_resamples": [("facemotion.regions.target:DEFAULT_RESAMPLES", None),
                                ("facemotion.regions.target:k_for_error", "resamples")],
    "eval.interval_level": [("facemotion.regions.target:DEFAULT_LEVEL", None),
                            ("facemotion.regions.target:k_for_error", "level")],
    "qr.noise_mm": [("facemotion.regions.redundancy:find_redundant_markers", "noise_mm")],
    "qr.min_copy_s": [("facemotion.regions.redundancy:find_redundant_markers",
                       "min_duration_s")],
    "qr.sweep_pivots": [("facemotion.ranking.stability:sentence_sweep", "n_pivots"),
                        ("facemotion.ranking.stability:stability", "n_pivots")],
    "qr.settle_tolerance": [("facemotion.ranking.stability:stability", "tolerance"),
                            ("facemotion.study.sweeps:evaluate_point", "settle_tolerance")],
    "qr.agreement_k": [("facemotion.ranking.stability:stability", "k_agree")],
    "qr.replicates": [("facemotion.ranking.stability:stability", "n_replicates")],
    "qr.seed": [("facemotion.ranking.stability:stability", "seed"),
                ("facemotion.ranking.routes:rank_markers", "seed"),
                ("facemotion.ranking.routes:rank_for_study", "seed")],
    "qr.optimality_k_max": [("facemotion.regions.optimality:subset_optimality", "k_max")],
    "qr.flag_pivots": [("facemotion.ranking.filled:FLAG_PIVOTS", None),
                       ("facemotion.ranking.filled:mostly_filled_pivots", "first_k")],
    "qr.flag_filled_fraction": [("facemotion.ranking.filled:FLAG_FILLED_FRACTION", None),
                                ("facemotion.ranking.filled:mostly_filled_pivots", "share")],
    "fit.grid_n": [("facemotion.plots.facemap:interpolate_field", "grid_n"),
                   ("facemotion.plots.regions:plot_region_maps", "grid_n"),
                   ("facemotion.plots.regions:plot_orthogonal_directions", "grid_n")],
    "fit.orthogonal_maps": [("facemotion.plots.regions:plot_orthogonal_directions",
                             "n_pivots")],
    "animation.grid_n": [("facemotion.plots.animation:FaceAnimation", "grid_n"),
                         ("facemotion.plots.animation:face_surface", "grid_n"),
                         ("facemotion.plots.animation:iter_frames", "grid_n"),
                         ("facemotion.plots.animation:render_frames", "grid_n"),
                         ("facemotion.plots.animation:still_frame", "grid_n")],
    "lips.n_modes": [("facemotion.lips.pipeline:run_lip_model", "n_modes"),
                     ("facemotion.lips.pipeline:LipSettings", "n_modes")],
    "lips.normalisation": [("facemotion.lips.pipeline:run_lip_model", "normalisation"),
                           ("facemotion.lips.pipeline:virtual_lip_study", "normalisation"),
                           ("facemotion.lips.pipeline:grid_lip_study", "normalisation"),
                           ("facemotion.lips.pipeline:LipSettings", "normalisation")],
    "lips.model_extent": [("facemotion.lips.pipeline:run_lip_model", "model_extent"),
                          ("facemotion.lips.pipeline:LipSettings", "model_extent"),
                          ("facemotion.lips.mesh:PAPER_MODEL_EXTENT", None)],
    # The library calls the schema's 'auto' 'ppca' (facemotion.study.settings.lip_settings
    # translates).
    "lips.noise_var": [("facemotion.lips.pipeline:run_lip_model", "noise_var",
                        {"auto": "ppca"}),
                       ("facemotion.lips.pipeline:LipSettings", "noise_var", {"auto": "ppca"})],
    "lips.noise_var_sweep": [("facemotion.lips.pipeline:run_lip_model", "noise_grid"),
                             ("facemotion.lips.pipeline:LipSettings", "noise_grid")],
    "lips.E": [("facemotion.lips.pipeline:run_lip_model", "E"),
               ("facemotion.lips.pipeline:LipSettings", "E"),
               ("facemotion.lips.fem:assemble_stiffness", "E")],
    "lips.nu": [("facemotion.lips.pipeline:run_lip_model", "nu"),
                ("facemotion.lips.pipeline:LipSettings", "nu"),
                ("facemotion.lips.fem:assemble_stiffness", "nu")],
    "figures.formats": [("facemotion.plots.save:figure_paths", "formats")],
    "memory.max_gib": [("facemotion.ingest.streaming:stream_dataset", "max_gib"),
                       ("facemotion.ingest.scatter:scan_heads", "max_gib")],
    "datasets.*.mesh_labels": [("facemotion.plots.face_mesh:DEFAULT_LABELS", None)],
}

#: Library defaults still to be brought to the schema's: each is expected to fail (strict), so
#: the fix that makes it pass also removes it from here.
KNOWN_DIFFERENCES: set[tuple[str, str]] = set()

#: Settings that no library function takes as a default: the workflow's own (paths, names,
#: which jobs run, table sizes) or ones whose library counterpart is deliberately different.
WORKFLOW_ONLY = {
    "study", "subjects", "shared_data", "default_datasets", "report_title",
    "qr.route_check", "qr.top_n", "qr.table_orders", "qr.max_filled_fraction",
    "fit.k", "eval.trajectory_marker", "eval.trajectory_sentence", "eval.trajectory_k",
    "eval.consensus",
    # design_markers chooses the set again in every resample unless told (NOT_THE_SETTING)
    "eval.selection_resamples",
    "animation.enabled", "animation.k", "animation.sentences", "animation.fps",
    "animation.format",
    # run_lip_model's defaults hold out the last 10 frames of however many there are; the
    # schema's 1-140 / 141-150 are the same split for the paper's 150 frames
    "lips.train_frames", "lips.test_frames",
    "virtual_talkers.n_talkers", "virtual_talkers.design", "virtual_talkers.n_sentences",
}

#: Library parameters named like a setting, with another default, that are not that setting.
NOT_THE_SETTING = {
    ("facemotion.regions.design", "subjects"): "the pilot sentences' subjects, not the sheet",
    ("facemotion.regions.design", "neutral"): "the marker set's rest positions (mm), not the "
                                              "neutral-pose mode",
    ("facemotion.regions.design", "k"): "the design's k: from the target error unless given",
    ("facemotion.regions.design", "selection_resamples"): "every resample unless told; the "
                                                          "workflow's setting bounds a study's "
                                                          "time",
    ("facemotion.regions.marker_set", "k"): "the design's k: from the target error unless given",
    ("facemotion.regions.marker_set", "subjects"): "each pilot take's subject, not the sheet",
    ("facemotion.ingest.loading", "sentences"): "the intervals of the takes, not how many "
                                                "sentences the animation shows",
    ("facemotion.ingest.streaming", "sentences"): "the intervals of the takes (as loading's)",
    ("facemotion.ingest.scatter", "sentences"): "a take's intervals (None: the whole take)",
    ("facemotion.lips", "n_modes"): "the generic PCA and LLSE keep every mode unless told",
    ("facemotion.lips.pca", "n_modes"): "the generic PCA keeps every mode unless told",
    ("facemotion.lips.llse", "n_modes"): "the generic LLSE uses every mode unless told",
    ("facemotion.lips", "noise_var"): "lips.reconstruct's generic LLSE: the noise-free limit",
    ("facemotion.lips.pipeline", "train_frames"): "all but the last 10 frames (WORKFLOW_ONLY)",
    ("facemotion.lips.pipeline", "test_frames"): "the last 10 frames (WORKFLOW_ONLY)",
    ("facemotion.study.sheet", "n_sentences"): "a sheet subject's sentences, not the talker "
                                               "sweep's",
    ("facemotion.lips.virtual", "noise_mm"): "the virtual lip talker's tracking noise, not the "
                                             "copy detector's noise floor",
    ("facemotion.ranking.result", "normalisation"): "qr.r_normalisation (mapped by that name)",
    ("facemotion.ranking.epsilon_rank", "normalisation"): "qr.r_normalisation (mapped)",
    ("facemotion.plots.selection", "k"): "None: every k of the table",
    ("facemotion.virtual.dense", "design"): "the dense designs, not the talker sweep's",
    ("facemotion.virtual.dense", "n_sentences"): "a dense subject's sentences (the sheet's)",
    ("facemotion.virtual.dense", "noise_mm"): "the simulated capture noise (None: the design's)",
    ("facemotion.virtual.talker", "noise_mm"): "the simulated capture noise",
    ("facemotion.virtual.talker", "n_sentences"): "None: the design's sentences",
    ("facemotion.virtual.talker", "seed"): "None: a marker layout's own stream",
    ("facemotion.virtual.files", "n_sentences"): "None: the design's sentences",
}


def compare(defaults: dict[str, object], mapping: dict[str, list[tuple]]) -> list[str]:
    """One line per library default that differs from the schema's default of its setting."""
    problems = []
    for setting, targets in sorted(mapping.items()):
        if setting not in defaults:
            problems.append(f"{setting}: no such setting with a default in the schema")
            continue
        for target, param, *names in targets:
            value = library_default(target, param)
            expected = defaults[setting]
            if names and isinstance(expected, str):
                expected = names[0].get(expected, expected)
            if plain(value) != plain(expected):
                where = f"{target}" + (f"({param}=...)" if param else "")
                problems.append(f"{setting}: schema {plain(expected)!r}, {where} "
                                f"{plain(value)!r}")
    return problems


@pytest.fixture(scope="module")
def schema():
    return yaml.safe_load(SCHEMA.read_text(encoding="utf-8"))


def mapping_items():
    for setting, targets in MAPPING.items():
        for entry in targets:
            marks = ([pytest.mark.xfail(strict=True, reason="library default differs")]
                     if (setting, entry[0]) in KNOWN_DIFFERENCES else [])
            yield pytest.param(setting, entry, marks=marks, id=f"{setting}-{entry[0]}")


@pytest.mark.parametrize("setting,entry", list(mapping_items()))
def test_library_default_equals_the_schemas(schema, setting, entry):
    assert compare(schema_defaults(schema), {setting: [entry]}) == []


def test_every_setting_is_mapped_or_workflow_only(schema):
    settings = set(schema_defaults(schema))
    assert set(MAPPING) | WORKFLOW_ONLY == settings, (
        f"unmapped: {sorted(settings - set(MAPPING) - WORKFLOW_ONLY)}; not settings: "
        f"{sorted((set(MAPPING) | WORKFLOW_ONLY) - settings)}")
    assert not set(MAPPING) & WORKFLOW_ONLY


def library_parameters():
    """(module, callable name, parameter, default) for every callable the package defines."""
    for info in pkgutil.walk_packages(facemotion.__path__, "facemotion."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if getattr(obj, "__module__", None) != module.__name__:
                continue
            callables = [(name, obj)]
            if inspect.isclass(obj):
                callables += [(f"{name}.{m}", f) for m, f in vars(obj).items()
                              if inspect.isfunction(f)]
            for qualname, fn in callables:
                try:
                    params = inspect.signature(fn).parameters.values()
                except (TypeError, ValueError):
                    continue
                for p in params:
                    if p.default is not inspect.Parameter.empty:
                        yield module.__name__, qualname, p.name, p.default


def test_no_other_library_parameter_named_like_a_setting_disagrees(schema):
    # A parameter named after a setting (its last part) is taken to be that setting unless it
    # is mapped or listed above as something else.
    defaults = schema_defaults(schema)
    by_name: dict[str, list] = {}
    for setting, value in defaults.items():
        by_name.setdefault(setting.rsplit(".", 1)[-1], []).append(plain(value))
    mapped = {(t[0], t[1]) for targets in MAPPING.values() for t in targets}
    problems = []
    for module, qualname, param, default in library_parameters():
        if param not in by_name or (f"{module}:{qualname.removesuffix('.__init__')}",
                                    param) in mapped:
            continue
        if (module, param) in NOT_THE_SETTING or plain(default) in by_name[param]:
            continue
        problems.append(f"{module}:{qualname}({param}={default!r}); the schema's "
                        f"{param}: {by_name[param]}")
    assert problems == []


def test_the_comparison_rejects_a_schema_that_moved(schema):
    changed = copy.deepcopy(schema)
    changed["properties"]["gaps"]["properties"]["max_interp_s"]["default"] = 0.2
    changed["properties"]["qr"]["properties"]["agreement_k"]["default"] = [5, 20]
    changed["properties"]["lips"]["properties"]["noise_var"]["default"] = 0.001
    mapping = {k: MAPPING[k] for k in ("gaps.max_interp_s", "qr.agreement_k", "lips.noise_var",
                                       "qr.method")}
    assert compare(schema_defaults(schema), mapping) == []
    assert compare(schema_defaults(changed), mapping) == [
        "gaps.max_interp_s: schema 0.2, facemotion.ingest.loading:load_dataset"
        "(max_interp_s=...) 0.1",
        "gaps.max_interp_s: schema 0.2, facemotion.ingest.gaps:fill_gaps(max_interp_s=...) 0.1",
        "lips.noise_var: schema 0.001, facemotion.lips.pipeline:run_lip_model(noise_var=...) "
        "'ppca'",
        "lips.noise_var: schema 0.001, facemotion.lips.pipeline:LipSettings(noise_var=...) "
        "'ppca'",
        "qr.agreement_k: schema [5, 20], facemotion.ranking.stability:stability(k_agree=...) "
        "[5, 10]",
    ]
    del changed["properties"]["qr"]["properties"]["method"]["default"]
    assert ("qr.method: no such setting with a default in the schema"
            in compare(schema_defaults(changed), mapping))


def test_load_and_the_command_line_leave_the_defaults_to_load_dataset(monkeypatch, schema):
    # facemotion.load and `facemotion rank` pass the loading settings on only when given, so
    # load_dataset's defaults (checked above) are theirs.
    from click.testing import CliRunner

    from facemotion import cli
    from facemotion.ingest import loading

    seen = {}

    def capture(recordings, fmt, **kw):
        seen.update(kw)
        raise SystemExit(0)

    monkeypatch.setattr(loading, "load_dataset", capture)
    with pytest.raises(SystemExit):
        loading.load(["a.c3d", "b.c3d"], heldout_sentences=[2])
    assert not {"max_interp_s", "long_gaps", "neutral", "limits"} & set(seen)
    seen.clear()
    CliRunner().invoke(cli.cli, ["rank", "a.c3d"], catch_exceptions=True)
    assert seen and not {"max_interp_s", "long_gaps", "neutral", "limits"} & set(seen)
    # what the help says the defaults are
    defaults = schema_defaults(schema)
    help_text = " ".join(CliRunner().invoke(cli.cli, ["rank", "--help"]).output.split())
    assert f"Default: the study's ({defaults['gaps.max_interp_s']:g} s)" in help_text
    assert f"Default: the study's ({defaults['gaps.long_gaps']})" in help_text
    assert f"Default: the study's ({defaults['neutral']})" in help_text
    rank = {p.name: p for p in cli.rank.params}
    assert rank["method"].default == defaults["qr.method"]
    assert rank["r_normalisation"].default == defaults["qr.r_normalisation"]


#: setting -> the library's list of its values
CHOICES = {
    "neutral": "facemotion.ingest.displacements:NEUTRAL_MODES",
    "gaps.long_gaps": "facemotion.ingest.gaps:LONG_GAP_METHODS",
    "gaps.outliers": "facemotion.ingest.validation:OUTLIER_MODES",
    "qr.method": "facemotion.ranking.routes:METHODS",
    "qr.r_normalisation": "facemotion.ranking.result:R_NORMALISATIONS",
    "animation.format": "facemotion.plots.animation:FORMATS",
    "figures.formats": "facemotion.plots.save:FIGURE_FORMATS",
}


def choice_problems(schema: dict) -> list[str]:
    settings = schema_settings(schema)
    problems = []
    for setting, target in CHOICES.items():
        spec = settings[setting]
        enum = spec.get("enum") or spec.get("items", {}).get("enum")
        if sorted(enum) != sorted(resolve(target)):
            problems.append(f"{setting}: schema {sorted(enum)}, {target} "
                            f"{sorted(resolve(target))}")
    return problems


def test_the_settings_choices_are_the_librarys(schema):
    assert choice_problems(schema) == []
    changed = copy.deepcopy(schema)
    changed["properties"]["qr"]["properties"]["method"]["enum"].remove("scipy")
    assert choice_problems(changed) == [
        "qr.method: schema ['auto', 'gram', 'randomized', 'tsqr'], "
        "facemotion.ranking.routes:METHODS ['auto', 'gram', 'randomized', 'scipy', 'tsqr']"]


def test_the_command_lines_choices_are_the_settings(schema):
    from facemotion import cli

    settings = schema_settings(schema)
    rank = {p.name: p for p in cli.rank.params}
    assert list(rank["long_gaps"].type.choices) == settings["gaps.long_gaps"]["enum"]
    assert list(rank["neutral"].type.choices) == settings["neutral"]["enum"]
    assert list(rank["r_normalisation"].type.choices) == settings["qr.r_normalisation"]["enum"]
    # every route but the randomized one, which needs k_max (an option rank does not have)
    assert sorted(rank["method"].type.choices) == sorted(
        set(settings["qr.method"]["enum"]) - {"randomized"})
