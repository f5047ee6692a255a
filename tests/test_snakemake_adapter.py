"""Rules over several datasets: one job, each dataset on its own, in forked workers with threads."""

import os
from pathlib import Path

import pytest
from standin import Names

from facemotion.errors import InputError
from facemotion.study.adapter import run_per_dataset


def _job(tmp_path: Path, threads: int, subjects: dict[str, str]):
    names = list(subjects)

    class SM:
        rule = "load_dataset"
        input = Names()
        output = Names(out=[str(tmp_path / f"{d}.txt") for d in names])
        params = Names(datasets=names, per_dataset={d: {"subject": s}
                                                    for d, s in subjects.items()})
        wildcards = Names()
        log = Names([str(tmp_path / "job.log")])

    SM.threads = threads
    return SM()


def _write_pid(sm, log, prov):
    if sm.params.subject == "bad":
        raise InputError("recording x.c3d: frame 3 is broken")
    Path(sm.output.out).write_text(f"{os.getpid()} {sm.params.subject}")


@pytest.mark.parametrize("threads", [1, 2])
def test_every_dataset_is_run_and_groups_stay_in_one_worker(tmp_path, threads):
    subjects = {"S2a": "S2a", "S2a_star": "S2a", "S1": "S1", "S2b": "S2b"}
    run_per_dataset(_job(tmp_path, threads, subjects), _write_pid,
                    group_by=lambda part: part.params.subject)
    got = {d: (tmp_path / f"{d}.txt").read_text().split() for d in subjects}
    assert {d: s for d, (_, s) in got.items()} == subjects  # each dataset its own params
    pids = {d: int(p) for d, (p, _) in got.items()}
    assert pids["S2a"] == pids["S2a_star"]  # a subject's datasets share one worker
    if threads == 1:
        assert set(pids.values()) == {os.getpid()}  # no workers: this process
    else:
        assert os.getpid() not in pids.values()  # forked workers did the work
    assert "done:" in (tmp_path / "job.log").read_text()


def test_an_error_in_a_worker_is_one_line_naming_the_dataset(tmp_path, capsys):
    subjects = {"S1": "S1", "B1": "bad", "S2": "S2"}
    with pytest.raises(SystemExit) as exc:
        run_per_dataset(_job(tmp_path, 2, subjects), _write_pid)
    assert exc.value.code == 1
    lines = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert lines == ["facemotion: load_dataset: dataset B1: recording x.c3d: frame 3 is "
                     "broken"]
    assert "Traceback" not in (tmp_path / "job.log").read_text()


def _stamp_start(sm, log, prov):
    import time

    Path(sm.output.out).write_text(str(time.monotonic()))
    time.sleep(0.4)


def test_the_costliest_groups_start_first(tmp_path):
    """With 2 workers and 4 one-dataset groups, the two costliest start together and the
    other two only when a worker is free, whatever their order in the rule."""
    subjects = {"A": "A", "B": "B", "C": "C", "D": "D"}
    costs = {"A": 1, "B": 5, "C": 2, "D": 9}
    run_per_dataset(_job(tmp_path, 2, subjects), _stamp_start,
                    cost=lambda part: costs[part.params.subject])
    start = {d: float((tmp_path / f"{d}.txt").read_text()) for d in subjects}
    first, last = sorted(start, key=start.get)[:2], sorted(start, key=start.get)[2:]
    assert sorted(first) == ["B", "D"] and sorted(last) == ["A", "C"]
    assert min(start[d] for d in last) - max(start[d] for d in first) > 0.2


def _record_preloaded(sm, log, prov):
    import sys

    Path(sm.output.out).write_text(f"{os.getpid()} {'tabnanny' in sys.modules}")


def test_preloaded_modules_are_imported_once_before_the_workers_fork(tmp_path):
    import sys

    sys.modules.pop("tabnanny", None)
    subjects = {"A": "A", "B": "B"}
    run_per_dataset(_job(tmp_path, 2, subjects), _record_preloaded, preload=("tabnanny",))
    seen = [(tmp_path / f"{d}.txt").read_text().split() for d in subjects]
    assert all(pid != str(os.getpid()) and flag == "True" for pid, flag in seen)
    assert "tabnanny" in sys.modules  # imported here, in the job, before forking


def _record_frozen(sm, log, prov):
    import gc

    Path(sm.output.out).write_text(str(gc.get_freeze_count()))


def test_a_step_runs_with_the_imported_objects_out_of_the_collectors_scans(tmp_path):
    import gc

    gc.unfreeze()
    run_per_dataset(_job(tmp_path, 1, {"A": "A"}), _record_frozen)
    gc.unfreeze()
    assert int((tmp_path / "A.txt").read_text()) > 10_000  # numpy, pandas, ... frozen


def _allocate(sm, log, prov):
    import numpy as np

    block = np.ones(40_000_000 // 8)  # 40 MB, touched
    Path(sm.output.out).write_text(str(block.sum()))


def test_the_log_ends_with_cpu_and_peak_memory(tmp_path):
    """The job's last log line: its CPU and its exact peak memory (getrusage), which the
    per-rule table reads (benchmarks/rule_times.py)."""
    import importlib.util
    import re

    run_per_dataset(_job(tmp_path, 1, {"A": "A"}), _allocate)
    last = (tmp_path / "job.log").read_text().strip().splitlines()[-1]
    m = re.search(r"peak memory (\d+) MB \(largest child process (\d+) MB\)", last)
    assert m and int(m.group(1)) >= 40, last
    spec = importlib.util.spec_from_file_location(
        "rule_times", Path(__file__).parents[1] / "benchmarks" / "rule_times.py")
    rule_times = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rule_times)
    cpu, startup, children, own_mb, child_mb = rule_times.DONE.findall(last)[-1]
    assert float(own_mb) == int(m.group(1)) and float(cpu) > 0
