"""The 0.1 module paths (facemotion._deprecated): each imports, warns once naming the module
that now holds it, and hands out the very objects of the new modules.

Every import runs in a fresh interpreter: a shim warns when it is first imported, and this
process has usually imported some of the paths (or their targets) already.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

from helpers import REPO

from facemotion._deprecated import OLD_PATHS, REMOVED_IN

#: 0.1 path and name -> the module that holds that name now (written out by hand, from the
#: 0.1 modules and the 0.2 layout, not read from OLD_PATHS).
SAMPLE = [
    ("pivoted_qr", "rank_markers", "ranking.routes"),
    ("pivoted_qr", "MarkerRanking", "ranking.result"),
    ("pivoted_qr", "epsilon_rank", "ranking.epsilon_rank"),
    ("readers", "read_trc", "io.trc"),
    ("readers", "read_c3d", "io.c3d"),
    ("readers", "read_recording", "io.registry"),
    ("provenance", "write_table", "study.provenance"),
    ("provenance", "SIDECAR_SUFFIX", "study.outputs"),
    ("sentence_sweep", "sentence_sweep", "ranking.stability"),
    ("lips.modes", "Modes", "lips.pca"),
    ("lips.study", "run_lip_model", "lips.pipeline"),
    ("input", "read_recording", "io.registry"),
    ("input.segments", "parse_spec", "ingest.segments"),
    ("subjects", "DEFAULT_HELDOUT_FRACTION", "study.sheet"),
    ("synth", "make_talker", "virtual.talker"),
    ("plots.errors", "plot_error_curves", "plots.error_curves"),
    ("snakemake_adapter", "run_step", "study.adapter"),
]


def run(code: str) -> str:
    """Run ``code`` in a fresh interpreter on this checkout's package; its stdout."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, env=env, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


IMPORT_EVERY_OLD_PATH = """
    import importlib, json, warnings
    from facemotion._deprecated import OLD_PATHS

    caught = {}
    for old in sorted(OLD_PATHS):  # a package's path before its modules'
        with warnings.catch_warnings(record=True) as ws:
            warnings.simplefilter("always")
            exec(f"import facemotion.{old}", {})
        caught[old] = [(w.category.__name__, str(w.message), w.filename) for w in ws
                       if "facemotion" in str(w.message)]
    modules = {}
    for old, targets in OLD_PATHS.items():
        for target in targets:
            try:
                importlib.import_module(f"facemotion.{target}")
                modules[target] = True
            except ImportError:
                modules[target] = False
    print(json.dumps({"caught": caught, "modules": modules}))
"""


def warning_problems(caught: dict, modules: dict, old_paths: dict) -> list[str]:
    """What is wrong with the warnings the imports of ``old_paths`` gave: each import gives
    exactly one DeprecationWarning, at the importing line, naming the old path, the release
    that removes it and its main new module, which imports."""
    problems = []
    for old, targets in sorted(old_paths.items()):
        ws = caught.get(old, [])
        if len(ws) != 1:
            problems.append(f"facemotion.{old}: {len(ws)} warnings, not one: {ws}")
            continue
        category, text, filename = ws[0]
        new = f"facemotion.{targets[0]}"
        if category != "DeprecationWarning":
            problems.append(f"facemotion.{old}: a {category}")
        if f"facemotion.{old} " not in text or new not in text or REMOVED_IN not in text:
            problems.append(f"facemotion.{old}: the warning does not name it, {new} and "
                            f"{REMOVED_IN}: {text!r}")
        if filename != "<string>":
            problems.append(f"facemotion.{old}: the warning points at {filename}, not at the "
                            "import")
        for target in targets:
            if not modules.get(target):
                problems.append(f"facemotion.{old}: its new module facemotion.{target} does "
                                "not import")
            if target in old_paths:
                problems.append(f"facemotion.{old}: points at another old path {target}")
    return problems


def test_every_old_path_imports_with_one_deprecation_warning_naming_the_new_module():
    out = json.loads(run(IMPORT_EVERY_OLD_PATH))
    assert len(out["caught"]) == len(OLD_PATHS) >= 40
    assert warning_problems(out["caught"], out["modules"], OLD_PATHS) == []


def test_the_warning_check_rejects_a_silent_or_misdirected_shim():
    good = ("DeprecationWarning", "facemotion.gram is deprecated and will be removed in "
            f"facemotion {REMOVED_IN}; import from facemotion.ranking.gram", "<string>")
    assert warning_problems({"gram": [good]}, {"ranking.gram": True},
                            {"gram": ("ranking.gram",)}) == []
    planted = {
        "silent": [],
        "gram": [good],
        "wrong": [good[:1] + ("facemotion.wrong is deprecated; import from facemotion.io",
                              "shim.py")],
    }
    problems = warning_problems(planted, {"ranking.gram": True, "ranking.gone": False},
                                {"silent": ("ranking.gram",), "gram": ("ranking.gone",),
                                 "wrong": ("ranking.gram",)})
    assert sorted(problems) == [
        "facemotion.gram: its new module facemotion.ranking.gone does not import",
        "facemotion.gram: the warning does not name it, facemotion.ranking.gone and "
        f"{REMOVED_IN}: {good[1]!r}",
        "facemotion.silent: 0 warnings, not one: []",
        "facemotion.wrong: the warning does not name it, facemotion.ranking.gram and "
        f"{REMOVED_IN}: 'facemotion.wrong is deprecated; import from facemotion.io'",
        "facemotion.wrong: the warning points at shim.py, not at the import",
    ]


def test_a_script_importing_an_old_path_sees_the_warning_by_default():
    # Python shows a DeprecationWarning by default only when it is attributed to __main__.
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    env.pop("PYTHONWARNINGS", None)
    done = subprocess.run([sys.executable, "-c", "import facemotion.pivoted_qr"],
                          capture_output=True, text=True, env=env, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "DeprecationWarning: facemotion.pivoted_qr is deprecated" in done.stderr
    assert "facemotion.ranking.routes" in done.stderr


def test_old_names_are_the_very_objects_of_the_new_modules():
    out = json.loads(run(f"""
        import importlib, json, warnings
        warnings.simplefilter("ignore", DeprecationWarning)
        same = {{}}
        for old, name, new in {SAMPLE!r}:
            a = getattr(importlib.import_module("facemotion." + old), name)
            b = getattr(importlib.import_module("facemotion." + new), name)
            same[f"{{old}}.{{name}}"] = a is b
        print(json.dumps(same))
    """))
    assert out == {f"{old}.{name}": True for old, name, _ in SAMPLE}


def test_every_name_defined_in_a_new_module_is_reachable_at_its_old_path():
    # Each class and function a target module defines, read through the old path, is that
    # object (or, when two targets define one name, the first target's).
    out = json.loads(run("""
        import importlib, inspect, json, warnings
        warnings.simplefilter("ignore", DeprecationWarning)
        from facemotion._deprecated import OLD_PATHS
        wrong, checked = [], 0
        for old, targets in OLD_PATHS.items():
            shim = importlib.import_module("facemotion." + old)
            seen = set()
            for target in targets:
                module = importlib.import_module("facemotion." + target)
                for name, obj in vars(module).items():
                    if (name.startswith("_") or name in seen
                            or not (inspect.isfunction(obj) or inspect.isclass(obj))
                            or obj.__module__ != module.__name__):
                        continue
                    checked += 1
                    if getattr(shim, name, None) is not obj:
                        wrong.append(f"{old}.{name} (from {target})")
                seen |= set(vars(module))
        print(json.dumps({"wrong": wrong, "checked": checked}))
    """))
    assert out["wrong"] == []
    assert out["checked"] > 200


def test_a_shim_never_replaces_a_function_of_the_same_name():
    # facemotion.sentence_sweep and facemotion.lips.modes are both an old module path and a
    # function of the API: importing the path leaves the function in place.
    out = json.loads(run("""
        import json, sys, warnings
        warnings.simplefilter("ignore", DeprecationWarning)
        import facemotion, facemotion.lips
        import facemotion.sentence_sweep
        import facemotion.lips.modes
        from facemotion.ranking.stability import sentence_sweep
        from facemotion.lips.pca import Modes
        with warnings.catch_warnings(record=True) as ws:
            warnings.simplefilter("always")
            import facemotion.study
            study_name = facemotion.study.study_name
        from facemotion.study.summary import study_name as new_study_name
        print(json.dumps({
            "sentence_sweep": facemotion.sentence_sweep is sentence_sweep,
            "old sentence_sweep module": sys.modules["facemotion.sentence_sweep"].sentence_sweep
            is sentence_sweep,
            "lips.modes": callable(facemotion.lips.modes)
            and facemotion.lips.modes.__module__ == "facemotion.lips",
            "lips.modes.Modes": sys.modules["facemotion.lips.modes"].Modes is Modes,
            "study.study_name": study_name is new_study_name,
            "study warning": [str(w.message) for w in ws],
        }))
    """))
    warned = out.pop("study warning")
    assert out == dict.fromkeys(out, True) and len(out) == 5
    assert len(warned) == 1 and "facemotion.study.summary.study_name" in warned[0]


def test_importing_the_package_and_its_modules_touches_no_old_path():
    run("""
        import warnings
        warnings.simplefilter("error")
        import sys
        import facemotion, facemotion.lips, facemotion.ranking.routes, facemotion.io.registry
        facemotion.sentence_sweep, facemotion.lips.modes, facemotion.read
        from facemotion._deprecated import OLD_PATHS
        loaded = [m for m in sys.modules if m.removeprefix("facemotion.") in OLD_PATHS]
        assert not loaded, loaded
    """)


#: 0.1 names dropped in 0.2 (CHANGELOG.md, "Removed"): the one-job-over-all-datasets helpers
#: and the constants the registries replace; since 0.2, the comparison's rule strings and
#: verdict function, which the rule objects of facemotion.papers.table replace.
REMOVED_IN_0_2 = {
    "paper_comparison.factor_verdict", "paper_comparison.RULE_EXACT",
    "paper_comparison.RULE_MARKER", "paper_comparison.RULE_1_5", "paper_comparison.RULE_1_5_10",
    "dense_talker.DENSE_FORMATS", "dense_talker.DENSE_TALKER_SEED", "snakemake_adapter.ACROSS",
    "snakemake_adapter.across_provenance", "snakemake_adapter.dataset_parts",
    "snakemake_adapter.figure_paths", "snakemake_adapter.run_per_dataset",
    "subjects.DESIGN_SENTENCES", "subjects.FORMATS", "synth.DESIGN_TALKERS",
}


def test_every_public_name_of_0_1_still_resolves_but_the_removed_ones():
    """tests/data/api_0_1.json lists the public names each 0.1 module defined (read from the
    0.1 sources); through the shims every one resolves, except the removals the changelog
    lists, and those are in the changelog."""
    api = json.loads((REPO / "tests" / "data" / "api_0_1.json").read_text())
    code = ("import importlib, json, sys, warnings\n"
            "warnings.simplefilter('ignore')\n"
            "api = json.loads(sys.argv[1]); missing = []\n"
            "for mod, names in api.items():\n"
            "    m = importlib.import_module('facemotion.' + mod)\n"
            "    missing += [f'{mod}.{n}' for n in names if not hasattr(m, n)]\n"
            "print(json.dumps(missing))\n")
    proc = subprocess.run([sys.executable, "-c", code, json.dumps(api)], capture_output=True,
                          text=True, check=True)
    assert set(json.loads(proc.stdout)) == REMOVED_IN_0_2
    changelog = (REPO / "CHANGELOG.md").read_text()
    removed = changelog[changelog.index("### Removed"):changelog.index("## [0.1.0]")]
    for name in REMOVED_IN_0_2:
        assert name.rsplit(".", 1)[1] in removed, name
