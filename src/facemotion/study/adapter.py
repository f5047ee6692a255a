"""What every workflow script shares: logging to the rule's log, provenance, clear errors.

A script is a thin adapter::

    from facemotion.study.adapter import run_step

    def main(sm, log, prov):
        ...  # read sm.input, call facemotion, write sm.output with provenance

    run_step(snakemake, main)
"""

from __future__ import annotations

import contextlib
import errno
import gc
import itertools
import logging
import os
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from types import SimpleNamespace

from facemotion.errors import FacemotionError
from facemotion.io.atomic import temp_prefix
from facemotion.study.provenance import Provenance

_WRITE_ERRORS = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO}


def _flatten(files) -> list[str]:
    out: list[str] = []
    for f in files:
        if isinstance(f, (list, tuple)):
            out.extend(_flatten(f))
        else:
            out.append(str(f))
    return out


def figure_paths(output, key: str = "png") -> list[str]:
    """A figure's files from a rule's outputs: the PNG named ``key`` (``png``, ``traj_png``)
    and the other formats of the ``figures.formats`` setting, named ``key`` with ``more`` for
    ``png`` (``more``, ``traj_more``; declared with ``fig_more()`` in common.smk)."""
    more = key[: -len("png")] + "more"
    extra = list(output[more]) if more in output.keys() else []
    return [str(output[key]), *map(str, extra)]


def provenance_for(sm, extra_inputs=()) -> Provenance:
    """Provenance of a Snakemake job: rule name, its params (the config used), its inputs and
    the outputs it declares."""
    params = {k: v for k, v in sm.params.items()} if hasattr(sm.params, "items") else {}
    wildcards = {k: v for k, v in sm.wildcards.items()} if hasattr(sm.wildcards, "items") else {}
    config = {"wildcards": wildcards, "params": params}
    files = [f for f in _flatten(sm.input) if os.path.isfile(f)] + list(extra_inputs)
    return Provenance(step=sm.rule, config=config, inputs=files,
                      job_outputs=_flatten(getattr(sm, "output", [])))


def clean_temporary_files(outputs) -> list[Path]:
    """Remove what an earlier, killed run of the job left beside its outputs: the hidden
    temporary files ``.<name>.<random>.tmp<suffix>`` of the atomic writers (and the older
    ``.<stem>.<random>.<suffix>`` form). Returns the files removed."""
    removed = []
    for out in map(Path, _flatten(outputs)):
        if not out.parent.is_dir():
            continue
        prefixes = (temp_prefix(out), f".{out.stem}.")
        for p in out.parent.iterdir():
            if p.name.startswith(prefixes) and p.is_file() and p != out:
                with contextlib.suppress(OSError):
                    p.unlink()
                    removed.append(p)
    return removed


def fault_message(exc: BaseException) -> str:
    """One line for a fault of the machine rather than of the data (disk full, file-size
    limit, out of memory), naming the file."""
    if isinstance(exc, MemoryError):
        return "out of memory"
    what = getattr(exc, "strerror", None) or (str(exc).strip().splitlines()
                                               or [type(exc).__name__])[0]
    if getattr(exc, "filename", None):
        verb = "cannot write" if exc.errno in _WRITE_ERRORS else "cannot access"
        return f"{verb} {exc.filename}: {what}"
    return what


class _Part:
    """Named files or params of one dataset's part of a job (attribute and item access)."""

    def __init__(self, values: dict):
        self._values = values

    def __getattr__(self, name):
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name):
        return self._values[name]

    def keys(self):
        return self._values.keys()

    def items(self):
        return self._values.items()


#: Outputs and params of a rule over several datasets that belong to the whole job (tables and
#: figures across datasets, see :func:`run_per_dataset`), not to one dataset.
ACROSS = "across_"


def dataset_parts(sm):
    """The datasets of a job that runs one step over several datasets, one at a time.

    A rule over datasets (`rank_markers`, `evaluate_heldout`, ...) names its datasets in
    ``params.datasets``; every named input and output is a list with one file per dataset, in
    that order; ``params.per_dataset`` maps a dataset to the params that concern it alone (its
    label); its entry ``inputs`` names inputs that only some datasets have, as lists of that
    dataset's files (e.g. ``{"mesh": [path]}`` or ``{"mesh": []}``; the rule's input of that name
    lists them all, for change detection). Yields ``(dataset, part, prov)``: ``part`` has
    ``input``, ``output``, ``params`` and ``wildcards`` as a job of that dataset alone would
    (``more`` and ``*_more``, a figure's other formats, are split into equal lists; the job's
    own wildcards, e.g. ``k``, are kept; ``params.part_wildcard`` names the dataset's wildcard,
    default ``dataset``), ``prov`` that dataset's provenance (its inputs only;
    its params; its wildcards), so the sidecars are those of a per-dataset job. One job
    instead of one per dataset: each job costs ~1 s of start-up.
    """
    datasets = list(sm.params.datasets)
    n = len(datasets)
    # the wildcard a job of one part alone would have: "dataset", or e.g. "lip_subject"
    name = sm.params.part_wildcard if "part_wildcard" in sm.params.keys() else "dataset"
    common = {k: v for k, v in sm.params.items()
              if k not in ("datasets", "per_dataset", "part_wildcard")
              and not k.startswith(ACROSS)}
    per = sm.params.per_dataset if "per_dataset" in sm.params.keys() else {}

    def pick(files, i, own=None):
        out = {}
        for k, v in files.items():
            if k.startswith(ACROSS):  # one output of the whole job: the gather step's
                continue
            if own is not None and k in own:
                out[k] = [str(f) for f in own[k]]
                continue
            v = [str(f) for f in v] if isinstance(v, (list, tuple)) else [str(v)]
            if k == "more" or k.endswith("_more"):
                # a figure's other formats (figs_more): the same number of files per dataset
                if len(v) % n:
                    raise ValueError(f"{sm.rule}: {k} has {len(v)} files for {n} datasets")
                m = len(v) // n
                out[k] = v[i * m:(i + 1) * m]
                continue
            if len(v) != n:
                raise ValueError(f"{sm.rule}: {k} has {len(v)} files for {n} datasets")
            out[k] = v[i]
        return out

    job_wildcards = dict(sm.wildcards.items()) if hasattr(sm.wildcards, "items") else {}
    for i, d in enumerate(datasets):
        mine = dict(per.get(d, {}))
        own_inputs = mine.pop("inputs", {})
        params = {**common, **mine}
        wildcards = {name: d, **{k: v for k, v in job_wildcards.items() if k != name}}
        part = SimpleNamespace(input=_Part(pick(sm.input, i, own_inputs)),
                               output=_Part(pick(sm.output, i)), params=_Part(params),
                               wildcards=_Part(wildcards), rule=sm.rule, log=sm.log)
        files = [f for f in _flatten(part.input._values.values()) if os.path.isfile(f)]
        prov = Provenance(step=sm.rule, config={"wildcards": wildcards, "params": params},
                          inputs=files, job_outputs=_flatten(part.output._values.values()))
        yield d, part, prov


def setup_logging(sm) -> logging.Logger:
    # a log that cannot be written (disk full) must not print logging's own traceback
    logging.raiseExceptions = False
    log = logging.getLogger("facemotion")
    log.setLevel(logging.INFO)
    for h in list(log.handlers):
        log.removeHandler(h)
    logs = _flatten(sm.log) if sm.log else []
    if logs:
        Path(logs[0]).parent.mkdir(parents=True, exist_ok=True)
        handler: logging.Handler = logging.FileHandler(logs[0], mode="w")
    else:
        handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(message)s"))
    log.addHandler(handler)
    return log


def run_step(sm, main: Callable) -> None:
    """Run ``main(sm, log, prov)``; a FacemotionError becomes one clear line and exit 1.

    A fault of the machine (disk full, file-size limit, out of memory) is one line too,
    naming the file. Outputs are written atomically by the provenance module, and Snakemake
    removes the outputs of a failed job, so nothing half-written is left behind; temporary
    files a killed run left are removed when the job starts again.
    """
    # no window system; set before matplotlib is imported (by the steps that draw, only)
    os.environ["MPLBACKEND"] = "Agg"
    started = time.process_time()  # CPU time of start-up: Python, Snakemake's preamble, imports
    # Everything alive now (the imported modules: about a million objects) stays alive for the
    # whole job: keep it out of the garbage collector's full scans, which the figures' many
    # short-lived objects trigger (5-10 % of a figure's CPU), and out of forked workers' pages.
    gc.freeze()
    log = setup_logging(sm)
    try:
        for p in clean_temporary_files(getattr(sm, "output", [])):
            log.info("removed %s, left by an earlier run of this job", p)
        main(sm, log, provenance_for(sm))
    except FacemotionError as exc:
        _fail(log, f"facemotion: {sm.rule}: {exc}")
    except (OSError, MemoryError) as exc:
        _fail(log, f"facemotion: {sm.rule}: {fault_message(exc)}")
    import resource

    kids = resource.getrusage(resource.RUSAGE_CHILDREN)  # worker processes, the MP4 encoder
    own = resource.getrusage(resource.RUSAGE_SELF)
    # peak resident memory, exact (the kernel's high-water mark; ru_maxrss is in KiB on Linux)
    log.info("done: %.2f s CPU, of which %.2f s start-up before the step (modules it imports "
             "while running are counted in the step), and %.2f s CPU in child processes; "
             "peak memory %.0f MB (largest child process %.0f MB)",
             time.process_time(), started, kids.ru_utime + kids.ru_stime,
             own.ru_maxrss * 1024 / 1e6, kids.ru_maxrss * 1024 / 1e6)


def _fail(log: logging.Logger, msg: str) -> None:
    """The one line of a failed job: in its log and on stderr; exit status 1."""
    log.error(msg)
    for h in log.handlers:
        with contextlib.suppress(Exception):
            h.flush()
    print(msg, file=sys.stderr, flush=True)
    sys.exit(1)


def across_provenance(sm, inputs: Iterable[str]) -> Provenance:
    """Provenance of the outputs across datasets of a rule over several datasets: the job's
    params as its config, ``inputs`` (files the job has just written per dataset) as its
    inputs, the ``across_*`` outputs as the job's outputs."""
    params = dict(sm.params.items())
    outputs = [v for k, v in sm.output.items() if k.startswith(ACROSS)]
    return Provenance(step=sm.rule, config={"wildcards": {}, "params": params},
                      inputs=[str(f) for f in inputs], job_outputs=_flatten(outputs))


def _run_group(main: Callable, group: list, log: logging.Logger) -> None:
    """``main`` for each (dataset, part, prov) of ``group``, in order; an error names the
    dataset."""
    for dataset, part, prov in group:
        # "dataset", or what the part's wildcard names (e.g. "lip subject")
        kind = next(iter(part.wildcards.keys())).replace("_", " ")
        log.info("%s %s", kind, dataset)
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            main(part, log, prov)
        except FacemotionError as exc:
            if dataset in str(exc):
                raise
            raise type(exc)(f"{kind} {dataset}: {exc}") from exc
        log.info("%s %s done in %.1f s (%.1f s CPU)", kind, dataset,
                 time.perf_counter() - wall, time.process_time() - cpu)


_FORKED: dict = {}  # what forked workers run: set before the pool forks, never pickled


def _run_group_in_worker(i: int) -> None:
    """Group ``i`` of :data:`_FORKED` in a forked worker, its BLAS at one thread (the job's
    threads are the workers)."""
    from facemotion.ranking.gram import blas_limit

    with blas_limit(1):
        _run_group(_FORKED["main"], _FORKED["groups"][i], logging.getLogger("facemotion"))


def run_per_dataset(sm, main: Callable, across: Callable | None = None,
                    group_by: Callable | None = None, cost: Callable | None = None,
                    preload: Iterable[str] = ()) -> None:
    """Run ``main(part, log, prov)`` for each dataset of a rule over several datasets (see
    :func:`dataset_parts`): the script is written as for one dataset; an error names the
    dataset. Then ``across(sm, log)``, if given: the step that draws or tabulates all datasets
    together (outputs and params named ``across_*``, left out of the per-dataset parts) from
    what the job has just written, in the same job instead of a job of its own (each job costs
    about a second of start-up).

    With more than one thread (the rule's ``threads``), the datasets are shared out among that
    many worker processes forked from this one (so they start with its modules imported), in
    groups that stay together in one worker and in order: consecutive datasets with the same
    ``group_by(part)`` (e.g. a subject, whose takes its datasets share). The groups start
    costliest first (the sum of ``cost(part)`` over a group's datasets, e.g. its number of
    recordings; default 1 a dataset), so that a long group does not start last and run alone.
    Modules named in ``preload`` (heavy imports the package makes lazily, where it uses them)
    are imported before the workers fork, once, instead of in every worker. Outputs are the
    same either way: every dataset is computed on its own, and an error is reported for the
    first failing dataset in dataset order.
    """

    def each(sm, log, _prov):
        parts = list(dataset_parts(sm))
        # consecutive (dataset, part, prov) with the same key; without group_by, one each
        groups = [list(g) for _, g in itertools.groupby(
            parts, key=(lambda item: group_by(item[1])) if group_by else (lambda item: item[0]))]
        workers = min(int(getattr(sm, "threads", 1) or 1), len(groups))
        if workers <= 1:
            _run_group(main, parts, log)
        else:
            import importlib
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            from concurrent.futures.process import BrokenProcessPool

            log.info("%d datasets in %d groups on %d worker processes", len(parts),
                     len(groups), workers)
            for h in log.handlers:
                h.flush()
            for module in preload:
                importlib.import_module(module)
            _FORKED.update(main=main, groups=groups)
            weight = cost or (lambda part: 1)
            longest_first = sorted(range(len(groups)),
                                   key=lambda i: -sum(weight(part) for _, part, _ in groups[i]))
            with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")
                                     ) as pool:
                futures = {i: pool.submit(_run_group_in_worker, i) for i in longest_first}
                try:
                    for f in (futures[i] for i in range(len(groups))):  # first error in order
                        f.result()
                except BrokenProcessPool as exc:
                    raise FacemotionError(f"a worker process of this job died ({exc}); with "
                                          "less memory per worker, give the rule fewer "
                                          "threads") from None
        if across is not None:
            log.info("all %d datasets together", len(sm.params.datasets))
            across(sm, log)

    run_step(sm, each)
