"""Library errors name the argument; the workflow's name the setting.

A function of the library is called by people who never saw the config file: ``method:
unknown ranking method 'x'`` tells them which argument to fix, ``setting qr.method: ...`` does
not. The Snakemake side (facemotion/study/, the rules and scripts) names the setting, passing
the name down where the library takes one (``Limits(names=...)``, ``get_design(where=...)``).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import REPO, SCHEMAS

from facemotion.errors import InputError

PACKAGE = REPO / "src" / "facemotion"
ERRORS = {"InputError", "FacemotionError", "ValueError"}


def setting_paths() -> list[str]:
    """Every dotted setting path of the config schema (``qr.method``, ``gaps.max_interp_s``)."""
    schema = yaml.safe_load((SCHEMAS / "config.schema.yaml").read_text(encoding="utf-8"))
    out = []
    for group, spec in schema["properties"].items():
        out += [f"{group}.{name}" for name in spec.get("properties", {})]
    return out


def names_a_setting(text: str, paths: list[str]) -> str | None:
    """What in a message names a setting of the workflow: the word, or a config path."""
    m = re.search(r"\bsettings?\b", text)
    if m:
        return m.group(0)
    return next((p for p in paths if re.search(rf"(?<![\w.]){re.escape(p)}\b", text)), None)


def raised_messages(source: str) -> list[tuple[int, str]]:
    """(line, the literal text) of each error raised with a message written in place; the
    parts of an f-string that are computed count as nothing."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call)):
            continue
        func = node.exc.func
        if getattr(func, "id", getattr(func, "attr", None)) not in ERRORS:
            continue
        parts = []
        for arg in node.exc.args:
            for sub in ast.walk(arg):
                if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                    parts.append(sub.value)
        out.append((node.lineno, "".join(parts)))
    return out


def library_violations(root: Path, paths: list[str]) -> list[str]:
    """Messages of the library (every module outside study/) that name a setting."""
    found = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        if rel.parts[0] == "study":
            continue
        for line, text in raised_messages(path.read_text(encoding="utf-8")):
            what = names_a_setting(text, paths)
            if what:
                found.append(f"{rel}:{line}: {what!r} in {text[:60]!r}")
    return found


def test_no_library_error_names_a_setting():
    assert library_violations(PACKAGE, setting_paths()) == []


def test_the_check_finds_a_planted_setting_in_a_library_message(tmp_path):
    paths = setting_paths()
    assert {"qr.method", "gaps.max_interp_s", "lips.train_frames"} <= set(paths)
    planted = {
        "ranking/bad.py": 'def f(m):\n    raise InputError(f"setting qr.method: {m!r}")\n',
        "lips/bad.py": 'def g(x):\n    if x:\n        raise InputError(\n'
                       '            "frames " f"{x} outside lips.train_frames")\n',
        "ingest/fine.py": 'def h(x):\n    raise InputError(f"max_interp_s: must be >= 0, '
                          'got {x}")\n',
        "study/fine.py": 'def s(m):\n    raise InputError(f"setting qr.method: {m!r}")\n',
    }
    for name, text in planted.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text, encoding="utf-8")
    assert library_violations(tmp_path, paths) == [
        "lips/bad.py:3: 'lips.train_frames' in 'frames  outside lips.train_frames'",
        "ranking/bad.py:2: 'setting' in 'setting qr.method: '",
    ]


# --- the entry points, called with a bad argument -------------------------------------------

def _A(n=6, frames=20, seed=0):
    return np.random.default_rng(seed).normal(size=(3 * frames, n))


def _labels(n=6):
    return [f"m{i}" for i in range(n)]


def _recording():
    from facemotion.io.recording import Recording

    pts = np.random.default_rng(1).normal(size=(30, 4, 3)) * 5 + np.arange(4)[None, :, None] * 40
    return Recording(["a", "b", "c", "d"], pts, 60.0, source="take.c3d")


def _ranking():
    from facemotion.ranking.routes import rank_markers

    return rank_markers(_A(), _labels())


def _mesh():
    from facemotion.lips.mesh import parametric_lip_mesh

    return parametric_lip_mesh()


def _call(name):
    """The call of the entry point ``name`` with one bad argument."""
    from facemotion import lips
    from facemotion.ingest.displacements import build_displacements
    from facemotion.ingest.gaps import fill_gaps
    from facemotion.ingest.validation import Limits
    from facemotion.io.registry import get_format
    from facemotion.lips.fem import assemble_stiffness, material_matrix
    from facemotion.lips.llse import LLSE
    from facemotion.lips.mesh import model_units_per_mm
    from facemotion.plots.save import figure_paths
    from facemotion.ranking.epsilon_rank import epsilon_rank
    from facemotion.ranking.routes import rank_for_study, rank_markers, study_route
    from facemotion.ranking.stability import sentence_sweep, stability
    from facemotion.regions.optimality import subset_optimality
    from facemotion.regions.redundancy import find_redundant_markers
    from facemotion.virtual.designs import get_design

    rows = np.repeat(np.arange(4), 15)  # 4 sentences of 5 frames (3 rows a frame)
    calls = {
        "method": lambda: rank_markers(_A(), _labels(), method="fast"),
        "k_max": lambda: rank_for_study(_A(), _labels(), method="randomized"),
        "method (route)": lambda: study_route(57, "fast"),
        "normalisation": lambda: epsilon_rank(_ranking(), [0.5], normalisation="size"),
        "long_gaps": lambda: fill_gaps(_recording(), long_gaps="drop"),
        "max_interp_s": lambda: fill_gaps(_recording(), max_interp_s=-1.0),
        "neutral": lambda: build_displacements(_recording(), neutral="last_frame"),
        "limits.outliers": lambda: Limits(outliers="drop"),
        "formats": lambda: figure_paths("fig", ["png", "gif"]),
        "E": lambda: assemble_stiffness(_mesh(), E=0.0),
        "nu": lambda: material_matrix(nu=0.5),
        "n_frames": lambda: lips.make_virtual_talker(n_frames=1),
        "n_modes": lambda: lips.modes(np.ones((4, 9)) + np.eye(4, 9), n_modes=50),
        "model_extent": lambda: model_units_per_mm(_mesh(), (1.0, 2.0)),
        "noise_var": lambda: LLSE.from_data(_A().T).estimate(np.zeros((1, 2)), [0, 1], -1.0),
        "k_max (optimality)": lambda: subset_optimality(_A(), _labels(), k_max=0),
        "noise_mm": lambda: find_redundant_markers(_A(), _labels(), rows, 60.0, noise_mm=0),
        "n_pivots": lambda: sentence_sweep(_A(), _labels(), rows, n_pivots=0),
        "tolerance": lambda: stability(_A(), _labels(), rows, n_pivots=4, k_agree=(2,),
                                       tolerance=0.0),
        "format": lambda: get_format("bvh"),
        "design": lambda: get_design("S9"),
    }
    return calls[name]


ENTRY_POINTS = ["method", "k_max", "method (route)", "normalisation", "long_gaps",
                "max_interp_s", "neutral", "limits.outliers", "formats", "E", "nu", "n_frames",
                "n_modes", "model_extent", "noise_var", "k_max (optimality)", "noise_mm",
                "n_pivots", "tolerance", "format", "design"]


@pytest.mark.parametrize("argument", ENTRY_POINTS)
def test_a_bad_argument_is_named_in_the_message_not_a_setting(argument):
    with pytest.raises(InputError) as err:
        _call(argument)()
    message = str(err.value)
    name = argument.split(" (")[0]
    assert message.startswith(f"{name}: "), message
    assert names_a_setting(message, setting_paths()) is None, message


def test_the_study_names_the_settings_it_passes_down():
    from facemotion.study.settings import limits_from_config

    gaps = {"max_distance_mm": 250, "max_speed_mm_s": 1000, "outliers": "drop"}
    checks = {"min_take_frames": 10, "face_spread_mm": [10, 300], "rate_hz": [10, 2000],
              "max_shape_rms_mm": 20}
    with pytest.raises(InputError, match=r"^setting gaps\.outliers: must be one of"):
        limits_from_config(gaps, checks)
    limits = limits_from_config({**gaps, "outliers": "gaps"}, checks)
    assert limits.name("rate_hz") == "setting checks.rate_hz"
    assert limits.name("max_speed_mm_s") == "setting gaps.max_speed_mm_s"
