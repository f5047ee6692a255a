"""facemotion: how the human face moves during speech.

Two classic analyses, reproducible end to end:

* independent kinematic regions by QR with column pivoting (Lucero & Munhall 2008, J. Acoust.
  Soc. Am. 124:2283);
* a finite-element lip model trained from data (Basu & Pentland 1997), in `facemotion.lips`.

From a file to the paper's quantities::

    import facemotion as fm

    take = fm.read("take.c3d")                      # labels, points (frames, markers, 3) mm
    data = fm.load(["s1.c3d", "s2.c3d"], heldout_sentences=[2],
                   head_markers=["ForeHead_M", "NoseTop", "Leye_Inside"],
                   exclude_markers=["ForeHead_M", "NoseTop", "Leye_Inside"])
    ranking = fm.rank_markers(data.train)           # A P = Q R (Sec. III)
    ranking.to_frame()                              # pivot order and r values
    fm.epsilon_rank(ranking, [0.5])                 # epsilon-rank (Sec. III)
    X = fm.fit_regions(ranking, k=10)               # X = R11^-1 R12 (Sec. III, eq. 4)
    fm.error_curve(ranking, data.heldout.A, data.heldout.labels)   # Fig. 10

The single steps are there too: `align_head` (rigid head motion), `fill_gaps`,
`displacement_matrix` (A from recordings), `predict`, `sentence_sweep`, and a scikit-learn
style `MarkerSelector` with forced-in and excluded markers.  Every name is imported on first
use, so ``import facemotion`` is cheap and needs neither Snakemake nor matplotlib.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

from facemotion import _deprecated
from facemotion._version import __version__ as __version__

_deprecated.install()  # the 0.1 module paths (facemotion.pivoted_qr, ...) for one release


def _in_snakemake_script() -> bool:
    """Whether this process is a Snakemake job running one of the workflow's scripts (its
    preamble leaves a ``snakemake`` object and ``__real_file__`` in ``__main__``)."""
    main = sys.modules.get("__main__")
    kind = type(getattr(main, "snakemake", None))
    return hasattr(main, "__real_file__") and kind.__module__.split(".")[0] == "snakemake"


if _in_snakemake_script():
    # The job's script imports numpy, pandas, SciPy and matplotlib next: about a million
    # objects, whose creation sets off the collector's full scans, which find nothing to free.
    # facemotion.study.adapter.run_step freezes them and turns the collector back on.
    import gc

    gc.disable()

# public name -> (module, attribute); imported on first access (PEP 562)
_LAZY = {
    "read": ("facemotion.io.registry", "read_recording"),
    "load": ("facemotion.ingest.loading", "load"),
    "align_head": ("facemotion.ingest.head_motion", "align_head"),
    "fill_gaps": ("facemotion.ingest.gaps", "fill_gaps"),
    "gap_report": ("facemotion.ingest.gaps", "gap_report"),
    "displacement_matrix": ("facemotion.ingest.displacements", "build_displacements"),
    "rank_markers": ("facemotion.ranking.routes", "rank_markers"),
    "epsilon_rank": ("facemotion.ranking.epsilon_rank", "epsilon_rank"),
    "fit_regions": ("facemotion.regions.prediction", "fit_coefficients"),
    "predict": ("facemotion.regions.prediction", "predict"),
    "error_curve": ("facemotion.regions.prediction", "error_curve"),
    "sentence_sweep": ("facemotion.ranking.stability", "sentence_sweep"),
    "MarkerSelector": ("facemotion.regions.selector", "MarkerSelector"),
    "selection_table": ("facemotion.ranking.result", "selection_table"),
    "Recording": ("facemotion.io.recording", "Recording"),
    "Displacements": ("facemotion.ingest.displacements", "Displacements"),
    "LoadedDataset": ("facemotion.ingest.loading", "LoadedDataset"),
    "MarkerRanking": ("facemotion.ranking.result", "MarkerRanking"),
    "InputError": ("facemotion.errors", "InputError"),
    "design": ("facemotion.regions.marker_set", "design"),
    "reconstruct": ("facemotion.regions.marker_set", "reconstruct"),
    "MarkerSetDesign": ("facemotion.regions.design", "MarkerSetDesign"),
}
_SUBMODULES = ("lips",)

__all__ = [  # the same names as _LAZY and _SUBMODULES (a literal list, for linters and pdoc)
    "read", "load", "align_head", "fill_gaps", "gap_report", "displacement_matrix",
    "rank_markers", "epsilon_rank", "fit_regions", "predict", "error_curve", "sentence_sweep",
    "MarkerSelector", "selection_table", "Recording", "Displacements", "LoadedDataset",
    "MarkerRanking", "InputError", "lips", "design", "reconstruct", "MarkerSetDesign",
]

if TYPE_CHECKING:  # for type checkers and IDEs; at run time the names load lazily
    from facemotion import lips
    from facemotion.errors import InputError
    from facemotion.ingest.displacements import Displacements
    from facemotion.ingest.displacements import build_displacements as displacement_matrix
    from facemotion.ingest.gaps import fill_gaps, gap_report
    from facemotion.ingest.head_motion import align_head
    from facemotion.ingest.loading import LoadedDataset, load
    from facemotion.io.recording import Recording
    from facemotion.io.registry import read_recording as read
    from facemotion.ranking.epsilon_rank import epsilon_rank
    from facemotion.ranking.result import MarkerRanking, selection_table
    from facemotion.ranking.routes import rank_markers
    from facemotion.ranking.stability import sentence_sweep
    from facemotion.regions.design import MarkerSetDesign
    from facemotion.regions.marker_set import design, reconstruct
    from facemotion.regions.prediction import error_curve, predict
    from facemotion.regions.prediction import fit_coefficients as fit_regions
    from facemotion.regions.selector import MarkerSelector


class _Package(types.ModuleType):
    """The package module, whose API names a module never replaces.

    Importing a submodule sets the package's attribute of that name to it; a deprecated 0.1
    path such as ``facemotion.sentence_sweep`` would otherwise replace the function of that
    name.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _LAZY and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        module, attr = _LAZY[name]
        value = getattr(importlib.import_module(module), attr)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"facemotion.{name}")
    else:
        raise AttributeError(f"module 'facemotion' has no attribute {name!r}")
    globals()[name] = value  # cache: later look-ups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
