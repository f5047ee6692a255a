"""The module paths of facemotion 0.1, kept for one release (until 0.3) as thin shims.

``import facemotion.pivoted_qr`` (and every other 0.1 path in ``OLD_PATHS``) still works: the
import gives a module that warns once (``DeprecationWarning``, naming the new place) and
looks each name up in the modules that now hold it. Nothing here is imported unless an old
path is.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
import types
import warnings

#: 0.1 module (under facemotion) -> the modules its names moved to, the main one first.
OLD_PATHS: dict[str, tuple[str, ...]] = {
    "animation": ("plots.animation",),
    "copy_fill": ("ingest.copy_fill",),
    "dense_talker": ("virtual.dense",),
    "displacement_file": ("ingest.displacement_file",),
    "displacements": ("ingest.displacements", "ingest.displacement_file"),
    "face_mesh": ("plots.face_mesh",),
    "gaps": ("ingest.gaps",),
    "gram": ("ranking.gram",),
    "head_motion": ("ingest.head_motion",),
    "input": ("ingest.segments", "io.registry"),
    "input.c3d_points": ("io.c3d_points",),
    "input.openface": ("io.openface",),
    "input.optitrack": ("io.optitrack",),
    "input.prefixes": ("io.prefixes",),
    "input.qualisys": ("io.qualisys",),
    "input.segments": ("ingest.segments",),
    "invocation": ("study.invocation",),
    "lips.modes": ("lips.pca",),
    "lips.plots": ("plots.lips",),
    "lips.study": ("lips.pipeline",),
    "loading": ("ingest.loading",),
    "manifest": ("study.manifest",),
    "paper_comparison": ("papers.comparison", "papers.table", "papers.lucero_munhall",
                         "papers.basu_pentland"),
    "pivoted_qr": ("ranking.routes", "ranking.result", "ranking.qr", "ranking.epsilon_rank"),
    "plots.errors": ("plots.error_curves",),
    "prediction": ("regions.prediction",),
    "provenance": ("study.provenance", "io.atomic", "io.npz", "plots.save", "study.outputs"),
    "randomized_selection": ("ranking.randomized",),
    "readers": ("io.registry", "io.base", "io.c3d", "io.trc", "io.wide_csv"),
    "recording": ("io.recording",),
    "redundancy": ("regions.redundancy",),
    "selector": ("regions.selector", "ranking.result"),
    "sentence_sweep": ("ranking.stability",),
    "settings": ("study.settings",),
    "snakemake_adapter": ("study.adapter",),
    "subjects": ("study.sheet",),
    "subset_optimality": ("regions.optimality",),
    "sweeps": ("study.sweeps",),
    "synth": ("virtual.talker", "papers.lucero_munhall"),
    "validation": ("ingest.validation",),
}
#: Names of 0.1 modules that exist now as modules or packages of their own, and the modules
#: that hold their former names (looked up by the module's ``__getattr__``).
MOVED_NAMES: dict[str, tuple[str, ...]] = {
    "study": ("study.summary",),
}
REMOVED_IN = "0.3"


def message(old: str, new: str) -> str:
    return (f"facemotion.{old} is deprecated and will be removed in facemotion {REMOVED_IN}; "
            f"import from facemotion.{new}")


def lookup(old: str, targets: tuple[str, ...], name: str):
    """``name`` from the first of ``targets`` (modules under facemotion) that has it."""
    for target in targets:
        module = importlib.import_module(f"facemotion.{target}")
        if hasattr(module, name):
            warnings.warn(message(f"{old}.{name}", f"{target}.{name}"), DeprecationWarning,
                          stacklevel=3)
            return getattr(module, name)
    raise AttributeError(f"module 'facemotion.{old}' has no attribute {name!r}")


class _Shim(types.ModuleType):
    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        old = self.__name__.removeprefix("facemotion.")
        for target in OLD_PATHS[old]:
            module = importlib.import_module(f"facemotion.{target}")
            if hasattr(module, name):
                value = getattr(module, name)
                setattr(self, name, value)
                return value
        raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")

    def __dir__(self):
        old = self.__name__.removeprefix("facemotion.")
        names = set()
        for target in OLD_PATHS[old]:
            names |= set(dir(importlib.import_module(f"facemotion.{target}")))
        return sorted(names)


class _Finder:
    """Finds ``facemotion.<old path>`` after the normal finders have not, and loads it (a
    meta path finder and loader; not derived from importlib.abc, whose import pulls in
    importlib.resources, tempfile and shutil: 12 ms at every start of every job)."""

    def find_spec(self, fullname, path=None, target=None):
        old = fullname.removeprefix("facemotion.")
        if fullname == old or old not in OLD_PATHS:
            return None
        is_package = any(k.startswith(old + ".") for k in OLD_PATHS)
        return importlib.machinery.ModuleSpec(fullname, self, is_package=is_package)

    def create_module(self, spec):
        module = _Shim(spec.name)
        if spec.submodule_search_locations is not None:
            module.__path__ = []
        return module

    def exec_module(self, module):
        old = module.__name__.removeprefix("facemotion.")
        module.__doc__ = f"Deprecated: {message(old, OLD_PATHS[old][0])}."
        warnings.warn(message(old, OLD_PATHS[old][0]), DeprecationWarning, stacklevel=2)


def install() -> None:
    """Put the finder for the 0.1 paths at the end of ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
