"""The script adapter: one job, its log, its one-line errors and the end of its process."""

import importlib.util
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from helpers import REPO, Names

from facemotion.errors import InputError
from facemotion.study.adapter import run_step


def _job(tmp_path: Path, name: str = "A"):
    class SM:
        rule = "load_dataset"
        input = Names()
        output = Names(out=str(tmp_path / f"{name}.txt"))
        params = Names(subject=name)
        wildcards = Names(dataset=name)
        log = Names([str(tmp_path / "job.log")])
        threads = 1

    return SM()


def _record_frozen(sm, log, prov):
    import gc

    Path(sm.output.out).write_text(str(gc.get_freeze_count()))


def test_a_step_runs_with_the_imported_objects_out_of_the_collectors_scans(tmp_path):
    import gc

    import numpy  # noqa: F401 (objects to freeze)

    gc.unfreeze()
    run_step(_job(tmp_path), _record_frozen)
    gc.unfreeze()
    assert int((tmp_path / "A.txt").read_text()) > 10_000  # numpy, pandas, ... frozen


def _allocate(sm, log, prov):
    import numpy as np

    block = np.ones(40_000_000 // 8)  # 40 MB, touched
    Path(sm.output.out).write_text(str(block.sum()))


def test_the_log_ends_with_cpu_and_peak_memory(tmp_path):
    """The job's last log line: its CPU and its exact peak memory (getrusage), which the
    per-rule table reads (benchmarks/rule_times.py)."""
    run_step(_job(tmp_path), _allocate)
    last = (tmp_path / "job.log").read_text().strip().splitlines()[-1]
    m = re.search(r"peak memory (\d+) MB \(largest child process (\d+) MB\)", last)
    assert m and int(m.group(1)) >= 40, last
    spec = importlib.util.spec_from_file_location(
        "rule_times", REPO / "benchmarks" / "rule_times.py")
    rule_times = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rule_times)
    cpu, startup, children, own_mb, child_mb = rule_times.DONE.findall(last)[-1]
    assert float(own_mb) == int(m.group(1)) and float(cpu) > 0


def _fails(sm, log, prov):
    raise InputError("recording x.c3d: frame 3 is broken")


def test_an_error_is_one_line_naming_the_rule_and_the_dataset(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        run_step(_job(tmp_path, "S2a_star"), _fails)
    assert exc.value.code == 1
    lines = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert lines == ["facemotion: load_dataset S2a_star: recording x.c3d: frame 3 is broken"]
    assert "Traceback" not in (tmp_path / "job.log").read_text()


JOB = textwrap.dedent('''
    import atexit, sys
    from pathlib import Path
    from facemotion.errors import InputError
    from facemotion.study.adapter import run_step

    out = Path(sys.argv[1])
    atexit.register(lambda: (out.parent / "teardown.txt").write_text("ran"))

    class Names(dict):
        __getattr__ = dict.__getitem__

    class Snakemake:  # what Snakemake's script preamble makes, by its name and package
        rule = "rank_markers"
        input, params, wildcards = Names(), Names(), Names()
        output = Names(out=str(out))
        log = [str(out.parent / "job.log")]
    Snakemake.__module__ = "snakemake.iocontainers"

    def main(sm, log, prov):
        if sys.argv[2] == "fail":
            raise InputError("a clear cause")
        out.write_text("written")
        log.info("the last step")

    run_step(Snakemake(), main)
    print("not reached")
''')


@pytest.mark.parametrize("outcome", ["ok", "fail"])
def test_a_jobs_own_process_ends_once_its_outputs_and_log_are_written(tmp_path, outcome):
    """In Snakemake's job process the interpreter's teardown is skipped (os._exit): the
    outputs and the log are complete, the exit status is the job's, and nothing after
    run_step runs (here: neither the last print nor an atexit handler)."""
    script = tmp_path / "job.py"
    script.write_text(JOB)
    proc = subprocess.run([sys.executable, str(script), str(tmp_path / "out.txt"), outcome],
                          capture_output=True, text=True, cwd=tmp_path)  # the study root
    log = (tmp_path / "job.log").read_text()
    assert "not reached" not in proc.stdout
    assert not (tmp_path / "teardown.txt").exists()
    if outcome == "ok":
        assert proc.returncode == 0, proc.stderr
        assert (tmp_path / "out.txt").read_text() == "written"
        assert "the last step" in log and "INFO done:" in log.splitlines()[-1]
    else:
        assert proc.returncode == 1
        assert proc.stderr.strip() == "facemotion: rank_markers: a clear cause"
        assert log.strip().endswith("facemotion: rank_markers: a clear cause")


SCRIPT = textwrap.dedent('''
    import gc, sys
    from pathlib import Path
    out = Path(sys.argv[1])

    class Snakemake:  # what Snakemake's script preamble leaves in __main__
        rule = "rank_markers"
        input = params = wildcards = {}
        output = {}
        log = [str(out.parent / "job.log")]
    Snakemake.__module__ = "snakemake.iocontainers"
    snakemake = Snakemake()
    if sys.argv[2] == "script":
        __real_file__ = __file__

    import facemotion.study.adapter as adapter  # the job script's imports
    during_imports = gc.isenabled()

    def main(sm, log, prov):
        out.write_text(f"{during_imports} {gc.isenabled()}")

    adapter.run_step(snakemake, main)
''')


@pytest.mark.parametrize("kind, expected", [("script", "False True"), ("other", "True True")])
def test_a_job_script_imports_with_the_collector_off_and_runs_its_step_with_it_on(
        tmp_path, kind, expected):
    """In a Snakemake script process the collector is off while the script imports its modules
    and on in the step; in any other process importing facemotion leaves it alone."""
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    subprocess.run([sys.executable, str(script), str(tmp_path / "out.txt"), kind], check=True,
                   cwd=tmp_path)  # a job runs in its study's root
    assert (tmp_path / "out.txt").read_text() == expected
