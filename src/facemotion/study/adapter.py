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
import logging
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

from facemotion.errors import FacemotionError
from facemotion.io.atomic import temp_prefix
from facemotion.study.outputs import check_inside_study
from facemotion.study.provenance import Provenance

#: the params entry that says where a job's input files lie (not recorded in sidecars)
FILES_AT = "files_at"
_WRITE_ERRORS = {errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO}


def _flatten(files) -> list[str]:
    out: list[str] = []
    for f in files:
        if isinstance(f, (list, tuple)):
            out.extend(_flatten(f))
        else:
            out.append(str(f))
    return out


def provenance_for(sm, extra_inputs=()) -> Provenance:
    """Provenance of a Snakemake job: rule name, its params (the config used), its inputs and
    the outputs it declares."""
    params = {k: v for k, v in sm.params.items()} if hasattr(sm.params, "items") else {}
    # where the input files lie (a rule's ``files_at`` param: the name the study records for
    # each file -> its path) is not a setting: sidecars name files by those names
    files_at = params.pop(FILES_AT, None) or {}
    wildcards = {k: v for k, v in sm.wildcards.items()} if hasattr(sm.wildcards, "items") else {}
    config = {"wildcards": wildcards, "params": params}
    files = [f for f in _flatten(sm.input) if os.path.isfile(f)] + list(extra_inputs)
    return Provenance(step=sm.rule, config=config, inputs=files,
                      job_outputs=_flatten(getattr(sm, "output", [])),
                      names={str(v): str(k) for k, v in files_at.items()})


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


def job_name(sm) -> str:
    """The rule and the job's wildcards, as its one-line errors name it (``load_dataset S1``,
    ``fit_regions S2a 10``)."""
    wildcards = dict(sm.wildcards.items()) if hasattr(sm.wildcards, "items") else {}
    return " ".join([sm.rule, *map(str, wildcards.values())])


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

    In a job's own process (``sm`` is Snakemake's script object), the process ends as soon as
    the outputs are written and the log is flushed: the interpreter's teardown of the modules a
    step imports (numpy, pandas, scipy, matplotlib: about a million objects) cost 0.16 CPU-s a
    job and changes nothing on disk.
    """
    # no window system; set before matplotlib is imported (by the steps that draw, only)
    os.environ["MPLBACKEND"] = "Agg"
    started = time.process_time()  # CPU time of start-up: Python, Snakemake's preamble, imports
    # Everything alive now (the imported modules: about a million objects) stays alive for the
    # whole job: keep it out of the garbage collector's full scans, which the figures' many
    # short-lived objects trigger (5-10 % of a figure's CPU), and out of forked workers' pages.
    gc.freeze()
    gc.enable()  # off while a job's script imports its modules (facemotion/__init__.py)
    if _in_job_process(sm):  # in a study's job, its working directory is the study root
        try:
            check_inside_study(_flatten(getattr(sm, "output", [])) + _flatten(sm.log or []))
        except FacemotionError as exc:
            print(f"facemotion: {job_name(sm)}: {exc}", file=sys.stderr, flush=True)
            _end(logging.getLogger("facemotion"), sm, 1)
    log = setup_logging(sm)
    try:
        for p in clean_temporary_files(getattr(sm, "output", [])):
            log.info("removed %s, left by an earlier run of this job", p)
        main(sm, log, provenance_for(sm))
    except FacemotionError as exc:
        _fail(log, sm, f"facemotion: {job_name(sm)}: {exc}")
    except (OSError, MemoryError) as exc:
        _fail(log, sm, f"facemotion: {job_name(sm)}: {fault_message(exc)}")
    import resource

    kids = resource.getrusage(resource.RUSAGE_CHILDREN)  # worker processes, the MP4 encoder
    own = resource.getrusage(resource.RUSAGE_SELF)
    # peak resident memory, exact (the kernel's high-water mark; ru_maxrss is in KiB on Linux)
    log.info("done: %.2f s CPU, of which %.2f s start-up before the step (modules it imports "
             "while running are counted in the step), and %.2f s CPU in child processes; "
             "peak memory %.0f MB (largest child process %.0f MB)",
             time.process_time(), started, kids.ru_utime + kids.ru_stime,
             own.ru_maxrss * 1024 / 1e6, kids.ru_maxrss * 1024 / 1e6)
    _end(log, sm, 0)


def _in_job_process(sm) -> bool:
    """Whether ``sm`` is the object Snakemake's script preamble made (in the job's own
    process), not a stand-in of a test or a caller."""
    kind = type(sm)
    return kind.__name__ == "Snakemake" and kind.__module__.split(".")[0] == "snakemake"


def _end(log: logging.Logger, sm, status: int) -> None:
    """Flush the log and the terminal; end a job's own process at once, else return (or
    raise SystemExit for a failure)."""
    for h in log.handlers:
        with contextlib.suppress(Exception):
            h.flush()
            h.close()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    if _in_job_process(sm):
        os._exit(status)
    if status:
        sys.exit(status)


def _fail(log: logging.Logger, sm, msg: str) -> None:
    """The one line of a failed job: in its log and on stderr; exit status 1."""
    log.error(msg)
    print(msg, file=sys.stderr, flush=True)
    _end(log, sm, 1)
