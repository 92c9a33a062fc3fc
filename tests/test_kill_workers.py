"""``kill -9`` of a run with worker processes leaves no process of the run alive 10 s later: the
Exp 5 tasks' joblib workers (``experiment.engine.n_jobs=2``) and the jobs of Hydra's joblib
launcher (an Exp 6 sweep), killed during training and during the tests. The process tree of the
run (every descendant of the killed process, and every process of its session) is listed just
before the kill; each of those processes must be gone within 10 s (the workers watch their
parent: neuroimagery/core/workers.py).

Slow (Exp 5 and Exp 6 quick runs, killed early): ``pytest -m slow tests/test_kill_workers.py``.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GONE_WITHIN_S = 10.0
EXP5 = ["experiment=exp5", "preset=quick", "experiment.quick.repetitions=1", "experiment.engine.n_jobs=2",
        "progress=false", "logger=none"]
EXP6 = ["-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "experiment=exp6", "preset=quick", "participants=1",
        "seed=0,1", "progress=false", "logger=none", "threads=1"]

# run before evaluate.py in the killed process: the tests phase of Exp 5 announces itself and waits,
# so that the kill comes while the tests run (the idle workers of the training still there)
SLOW_TESTS = """
import dataclasses, time, neuroimagery.experiments.exp5 as e
_evaluate = e.EXPERIMENT.evaluate
def evaluate(*a, **k):
    open({marker!r}, 'w').close(); time.sleep(300)
    return _evaluate(*a, **k)
e.EXPERIMENT = dataclasses.replace(e.EXPERIMENT, evaluate=evaluate)
"""


def _stat(pid: int) -> tuple[int, int, int] | None:
    """(parent PID, session id, start time) of process ``pid``; None when it is gone (or a zombie)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    if fields[0] == "Z":
        return None
    return int(fields[1]), int(fields[3]), int(fields[19])


def _processes() -> dict[int, tuple[int, int, int]]:
    out = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            st = _stat(int(d))
            if st is not None:
                out[int(d)] = st
    return out


def tree(root: int) -> dict[int, int]:
    """``{pid: start time}`` of the processes of the run ``root``: its descendants and the members
    of its session (the run is started in a session of its own)."""
    procs = _processes()
    found = {p for p, (_, sid, _) in procs.items() if sid == root and p != root}
    todo = [root]
    while todo:
        parent = todo.pop()
        kids = [p for p, (pp, _, _) in procs.items() if pp == parent]
        found.update(kids)
        todo.extend(kids)
    return {p: procs[p][2] for p in found if p in procs}


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return "?"


def _start(args: list[str], cwd: Path, prelude: str = "") -> subprocess.Popen:
    code = ("import runpy, sys\n" + prelude + f"\nsys.argv = ['evaluate.py', *{args!r}]\n"
            f"runpy.run_path({str(ROOT / 'evaluate.py')!r}, run_name='__main__')\n")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-c", code], cwd=cwd, env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _wait_for(cond, proc: subprocess.Popen, what: str, limit_s: float = 900.0) -> None:
    t0 = time.monotonic()
    while not cond():
        if proc.poll() is not None:
            raise AssertionError(f"the run ended ({proc.returncode}) before {what}: {proc.stderr.read()[-2000:]!r}")
        if time.monotonic() - t0 > limit_s:
            raise AssertionError(f"no {what} within {limit_s:.0f} s")
        time.sleep(0.2)


def _kill_and_check(proc: subprocess.Popen, min_workers: int) -> None:
    """``kill -9`` the run; every process of its tree must be gone within :data:`GONE_WITHIN_S`."""
    before = tree(proc.pid)
    assert proc.poll() is None, "the run ended before the kill"
    assert len(before) >= min_workers, {p: _cmdline(p) for p in before}
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    t0 = time.monotonic()
    alive = before
    try:
        while alive and time.monotonic() - t0 < GONE_WITHIN_S:
            time.sleep(0.25)
            alive = {p: t for p, t in alive.items() if (_stat(p) or (0, 0, None))[2] == t}
        assert not alive, f"alive {GONE_WITHIN_S:.0f} s after the kill: " + "; ".join(
            f"{p}: {_cmdline(p)[:120]}" for p in alive)
    finally:
        for p in alive:  # never leave them to the machine
            try:
                os.kill(p, signal.SIGKILL)
            except OSError:
                pass


def _workers(proc: subprocess.Popen) -> int:
    return sum("popen_loky_posix" in _cmdline(p) for p in tree(proc.pid))


def _manifests(d: Path) -> list[dict]:
    out = []
    for m in d.rglob("manifest.json"):
        try:
            out.append(json.loads(m.read_text()))
        except (OSError, ValueError):
            pass
    return out


@pytest.mark.slow
def test_exp5_killed_while_training_leaves_no_worker(tmp_path):
    proc = _start([*EXP5, f"hydra.run.dir={tmp_path / 'run'}"], tmp_path)
    _wait_for(lambda: _workers(proc) >= 2, proc, "two workers")
    time.sleep(2.0)  # the workers are computing tasks
    _kill_and_check(proc, min_workers=2)


@pytest.mark.slow
def test_exp5_killed_while_testing_leaves_no_worker(tmp_path):
    marker = tmp_path / "testing"
    proc = _start([*EXP5, f"hydra.run.dir={tmp_path / 'run'}"], tmp_path, SLOW_TESTS.format(marker=str(marker)))
    _wait_for(marker.exists, proc, "the tests")
    assert _workers(proc) >= 1  # the training's workers, idle
    _kill_and_check(proc, min_workers=1)


@pytest.mark.slow
@pytest.mark.parametrize("phase", ["training", "testing"])
def test_an_exp6_sweep_of_the_joblib_launcher_killed_leaves_no_job(tmp_path, phase):
    sweep = tmp_path / "sweep"
    proc = _start([*EXP6, f"hydra.sweep.dir={sweep}"], tmp_path)
    if phase == "training":
        _wait_for(lambda: len(_manifests(sweep)) >= 2, proc, "two jobs claiming their directories")
    else:
        _wait_for(lambda: any(m.get("trained") for m in _manifests(sweep)), proc, "a job testing")
    assert _workers(proc) >= 2
    _kill_and_check(proc, min_workers=2)
