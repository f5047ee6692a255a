"""Where the user typed the command: paths given on the command line, and a clean failed parse.

Snakemake changes to ``--directory`` before it reads the Snakefile, so a relative path given with
``--config subjects=SHEET`` would otherwise be read from there, not from where the user typed it.
Snakemake records the directory it was started in (``workflow.rundir``, the "Run directory" of
its log header); it is checked against ``--directory`` and the shell's ``PWD`` before use.
"""

from __future__ import annotations

import atexit
import os
from pathlib import Path

from facemotion.errors import InputError

#: set by the first (main) Snakemake process for the jobs it submits (a cluster job's Snakemake
#: starts in the working directory, not where the user typed the command)
ENV = "FACEMOTION_INVOCATION"


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def invocation_dir(rundir: str | Path | None, workdir_arg: str | Path | None,
                   cwd: str | Path | None = None, env: dict | None = None) -> Path | None:
    """The directory the user started Snakemake in, or None if it cannot be told for sure.

    ``rundir`` is Snakemake's record of where it was started, ``workdir_arg`` the value of
    ``--directory`` as typed (None without it), ``cwd`` the current (working) directory. A
    candidate is accepted only if ``--directory`` taken from it leads to the working directory.
    """
    cwd = Path(cwd or os.getcwd()).absolute()
    env = os.environ if env is None else env
    if workdir_arg is None:
        return cwd  # no --directory: Snakemake never changed directory
    wd = Path(workdir_arg)
    recorded = env.get(ENV, "")
    candidates = []
    if "\n" in recorded:  # "invocation dir\nworking dir" from the main process
        inv, work = recorded.split("\n", 1)
        if _same(Path(work), cwd):
            candidates.append(Path(inv))
    candidates += [Path(p) for p in (rundir, env.get("PWD")) if p]
    for cand in candidates:
        if not cand.is_absolute():
            continue
        if wd.is_absolute() or _same(cand / wd, cwd):
            # an absolute --directory says nothing about where the user was: trust Snakemake's
            # record (the first candidate) only
            return cand
    return None


def remember_invocation(inv: Path | None, cwd: str | Path | None = None) -> None:
    """Tell the jobs this process submits where the user typed the command."""
    if inv is not None and ENV not in os.environ:
        os.environ[ENV] = f"{inv}\n{Path(cwd or os.getcwd()).absolute()}"


def resolve_path(value: str, setting: str, *, from_command_line: bool, inv: Path | None,
                 repo: Path | None, what: str, must_exist: bool = True) -> Path:
    """A path setting: absolute as given; from ``--config``, relative to where the user typed
    the command; from a config file, relative to the working directory, else to the repository.

    A missing path is an InputError that says every place it looked.
    """
    p = Path(value).expanduser()
    if p.is_absolute():
        looked = [p]
    elif from_command_line:
        if inv is None:
            raise InputError(
                f"setting {setting}: {value} is relative, but the directory snakemake was "
                "started in cannot be told (--directory is absolute and differs from the "
                "shell's PWD); give an absolute path")
        looked = [inv / p]
    else:
        looked = [Path.cwd() / p] + ([repo / p] if repo is not None else [])
    for cand in looked:
        if cand.exists():
            return cand
    if not must_exist:
        return looked[0]
    rule = ("relative to the directory snakemake was started in" if from_command_line
            and not p.is_absolute() else
            "relative to the working directory, then the repository" if not p.is_absolute()
            else "absolute")
    raise InputError(f"setting {setting}: {what} {value} not found; looked for "
                     f"{' and '.join(str(c) for c in looked)} ({rule})")


class ParseGuard:
    """Removes what Snakemake created for this run if the Snakefile fails to parse.

    Snakemake creates ``.snakemake/log/<run>.snakemake.log`` before it reads the Snakefile; a
    run stopped by a bad setting should leave no trace. Only this run's log files are removed,
    and the folders only if they are then empty. Call :meth:`done` at the end of the Snakefile.
    """

    def __init__(self, logfiles, workdir: str | Path | None = None):
        self.logfiles = [Path(f) for f in logfiles]
        self.workdir = Path(workdir or os.getcwd()).absolute()
        self.ok = False
        atexit.register(self._cleanup)

    def done(self) -> None:
        self.ok = True

    def _cleanup(self) -> None:
        if self.ok:
            return
        meta = self.workdir / ".snakemake"
        for f in self.logfiles:
            if f.parent == meta / "log":
                f.unlink(missing_ok=True)
        for d in (meta / "log", meta):
            try:
                d.rmdir()  # only if empty: an earlier run's metadata stays
            except OSError:
                break



#: options that say which study a command runs; kept when another command is suggested
_STUDY_OPTIONS = ("-s", "--snakefile", "-d", "--directory", "--configfile", "--configfiles",
                  "--config", "-C", "--profile", "--workflow-profile")


def _snakemake_executable(argv0: str) -> str:
    """How to call the snakemake that runs now: ``snakemake`` when that name finds it on the
    PATH, else its path (relative to the current directory when inside it, e.g.
    ``.venv/bin/snakemake`` after ``make study``)."""
    import shutil

    exe = Path(argv0)
    if exe.name != "snakemake" or not exe.is_file():
        return "snakemake"   # python -m snakemake, or an unknown launcher
    found = shutil.which("snakemake")
    if found and Path(found).resolve() == exe.resolve():
        return "snakemake"
    try:
        return str(exe.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(exe.resolve())


def same_study_command(argv: list[str], *extra: str) -> str:
    """The command line that addresses the same study as ``argv`` (Snakefile, directory,
    config files, --config values, profile), followed by ``extra``; for the closing summary's
    report hint."""
    import shlex

    keep = [_snakemake_executable(argv[0] if argv else "")]
    args = list(argv[1:])
    i = 0
    while i < len(args):
        a = args[i]
        name = a.split("=", 1)[0]
        if name in _STUDY_OPTIONS:
            keep.append(a)
            i += 1
            if "=" not in a:
                while i < len(args) and not args[i].startswith("-"):
                    keep.append(args[i])
                    i += 1
            continue
        i += 1
    return shlex.join(keep + list(extra))


def sample_benchmarks_every(seconds: float) -> bool:
    """Snakemake's ``benchmark:`` sampling every ``seconds`` instead of twice a second.

    For a job's first 30 samples, Snakemake (``snakemake.benchmark``) samples its processes
    every 0.5 s, and each sample reads every process's memory map (psutil's
    ``memory_full_info``: about 8 ms for a Python process with numpy and matplotlib loaded).
    Over the default study that was about 4 s of CPU in Snakemake's own process, beside the
    jobs. Only the benchmark files' memory columns (maxima over the samples) depend on the
    sampling, not their wall time; each job logs its exact peak memory instead
    (``run_step``). Returns False, and changes nothing, if this Snakemake has no such
    setting."""
    try:
        import snakemake.benchmark as bench
    except ImportError:
        return False
    if not isinstance(getattr(bench, "BENCHMARK_INTERVAL_SHORT", None), (int, float)):
        return False
    bench.BENCHMARK_INTERVAL_SHORT = float(seconds)
    return True
