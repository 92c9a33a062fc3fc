"""Experiment 5 run directories under stress: planted files, interrupts, failed writes, broken runs.

Runs use the STAND-IN environment of ``tests/support_tool_env.py`` (not the robot).
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))
from conftest import make_cfg  # noqa: E402

import neuroimagery.app.run as R  # noqa: E402
from neuroimagery.app.cli import friendly_errors  # noqa: E402
from neuroimagery.app import pool  # noqa: E402
from neuroimagery.config import validate  # noqa: E402
from neuroimagery.core.errors import UserInputError  # noqa: E402
from neuroimagery.experiments.exp5 import protocol as exp5, pool as exp5_pool, tasks as exp5_tasks  # noqa: E402
from neuroimagery.core.files import tmp_path as tmp_name  # noqa: E402

STANDIN = "support_tool_env:StandInToolEnv"
ARGS = ("preset=quick", f"experiment.world.environment={STANDIN}", "experiment.engine.n_jobs=1",
        "experiment.quick.repetitions=1", "experiment.acquisition.max_epochs=2", "experiment.acquisition.explore_max_rollouts=120",
        "experiment.hp1_levels=[2,6]", "experiment.hp1_ages=[14,22]", "experiment.hp2_trials=[0,4]",
        "experiment.hp2_ages=[14,16]", "logger=none", "progress=false")


def compose(*overrides):
    return make_cfg("experiment=exp5", *ARGS, *overrides)


def as_run_of(d: Path, cfg, keys=()) -> None:
    """Make ``d`` a run directory of ``cfg`` (its manifest, and an index of ``keys`` when given), as a
    run that was stopped or finished would have left it."""
    from neuroimagery.core import manifest as mf
    from neuroimagery.config import experiment, validate

    conf = validate(cfg)
    rd = R.RunDir(d, conf, manifest=mf.build(conf, experiment("exp5")))
    if keys:
        rd.save_checkpoint("exp5_index", {"keys": list(keys), "seed": conf.seed})
    rd.close(ok=bool(keys), stopped="stopped")  # finished (with its index) or stopped; the lock released


def one_error_line(capsys) -> str:
    """The one ``error:`` line on stderr (``note:`` lines, e.g. that a run resumes, may come before)."""
    lines = capsys.readouterr().err.splitlines()
    errors = [ln for ln in lines if ln.startswith("error: ")]
    assert len(errors) == 1 and all(ln.startswith(("error: ", "note: ")) for ln in lines), lines
    return errors[0] + "\n"


# ---------------------------------------------------------------------------------- planted files
class Planted:
    """Unpickled in full, this touches ``marker``: the code a crafted task file could run."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def plant(path: Path, marker: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"task": {}, "rows": [], "library": {}, "timing": {}, "config": {}, "seed": 0, "x": Planted(marker)},
               path)


def test_a_planted_file_would_run_code_when_unpickled_in_full(tmp_path):
    """The file the tests below plant does run code under weights_only=False."""
    marker = tmp_path / "ran"
    plant(tmp_path / "f.pt", marker)
    torch.load(tmp_path / "f.pt", weights_only=False)
    assert marker.exists()


@pytest.mark.parametrize("where", ["resumed run", "reuse_libraries", "checkpoint"])
def test_a_planted_task_file_is_refused_and_nothing_in_it_runs(tmp_path, capsys, where):
    marker, run, other = tmp_path / "ran", tmp_path / "run", tmp_path / "other"
    key = "rep000_behind" if where == "checkpoint" else "rep000_far"  # checkpoint= reads in task order
    planted = exp5._task_path(run if where == "resumed run" else other, key)
    extra = {"resumed run": (), "reuse_libraries": (f"experiment.engine.reuse_libraries={other}",),
             "checkpoint": (f"checkpoint={other}",)}[where]
    if where == "resumed run":
        as_run_of(run, compose())
    elif where == "checkpoint":
        as_run_of(other, compose(), keys=[t["key"] for t in exp5.tasks(validate(compose()))])
    plant(planted, marker)
    with pytest.raises(SystemExit) as ex:
        friendly_errors(R.evaluate)(compose(*extra), out_dir=run)
    assert ex.value.code == 2
    err = one_error_line(capsys)
    assert str(planted) in err and "refused" in err and "plain data" in err
    assert not marker.exists()
    assert not exp5._task_path(run, "rep000_behind").exists()  # every file is read before any task runs


@pytest.mark.parametrize("content, why", [
    (b"", "not a readable task file"),
    (b"not a torch file\n", "not a readable task file"),
    (b"rows,success\n1,0\n", "not a readable task file"),
    ("list", "not an Exp 5 task file"),
])
def test_a_broken_task_file_is_refused_naming_it(tmp_path, content, why):
    path = exp5._task_path(tmp_path, "rep000_behind")
    as_run_of(tmp_path, compose())
    if content == "list":
        torch.save([1, 2], path)
    else:
        path.write_bytes(content)
    with pytest.raises(UserInputError, match=why) as ex:
        R.evaluate(compose(), out_dir=tmp_path)
    assert str(path) in str(ex.value) and "\n" not in str(ex.value)


def test_task_files_the_run_writes_load_as_plain_data(tmp_path):
    R.evaluate(compose(), out_dir=tmp_path)
    files = sorted((tmp_path / "checkpoints").glob("exp5_*.pt"))
    assert len(files) == 3  # two tasks and the index
    for f in files:
        assert isinstance(torch.load(f, weights_only=True), dict)


# ---------------------------------------------------------------------------------- failed writes
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (every write: no space left)")
def test_a_failed_write_names_the_path_and_keeps_the_tasks_finished_before(tmp_path, capsys):
    first, second = exp5._task_path(tmp_path, "rep000_behind"), exp5._task_path(tmp_path, "rep000_far")
    full = tmp_name(second)  # where this process writes the second task: a full disk
    full.parent.mkdir(parents=True)
    full.symlink_to("/dev/full")
    with pytest.raises(SystemExit) as ex:
        friendly_errors(R.evaluate)(compose(), out_dir=tmp_path)
    assert ex.value.code == 2
    assert one_error_line(capsys) == f"error: cannot write {second}: No space left on device\n"
    assert exp5_tasks.read_task(first)["task"]["key"] == "rep000_behind" and not second.exists()
    assert not list((tmp_path / "checkpoints").glob("*.tmp"))  # the temporary name is cleared


# ---------------------------------------------------------------------------------- interrupts
def test_only_temporary_files_of_finished_writers_are_removed(tmp_path):
    gone = subprocess.Popen([sys.executable, "-c", ""])
    gone.wait()
    stale = tmp_path / f"exp5_rep000_far.pt.{gone.pid}.tmp"
    live = tmp_name(tmp_path / "exp5_rep001_far.pt")  # this process's: still being written
    other = tmp_path / f"notes.txt.{gone.pid}.tmp"  # not a task file
    for p in (stale, live, other):
        p.write_bytes(b"x")
    assert exp5_tasks.remove_stale(tmp_path) == [stale]
    assert live.exists() and other.exists() and not stale.exists()


def test_sigterm_becomes_a_keyboard_interrupt_and_the_handler_is_restored(capsys):
    def stopped_by_sigterm():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
        pytest.fail("SIGTERM did not interrupt")

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(SystemExit) as ex:
        friendly_errors(stopped_by_sigterm)()
    assert ex.value.code == 130 and capsys.readouterr().err.startswith("interrupted:")
    assert signal.getsignal(signal.SIGTERM) is before


def _loky_workers() -> list[int]:
    """Pids of this process's children that are joblib (loky) workers."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            ppid = int(stat.read_text().rsplit(")", 1)[1].split()[1])
            cmd = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError, ValueError):
            continue
        if ppid == os.getpid() and b"popen_loky" in cmd:
            out.append(int(stat.parent.name))
    return out


@pytest.fixture(scope="module")
def two_rep_reference(tmp_path_factory):
    """individuals.csv of an uninterrupted run of 4 tasks (2 repetitions x 2 situations)."""
    d = tmp_path_factory.mktemp("ref")
    R.evaluate(compose("experiment.quick.repetitions=2"), out_dir=d)
    return pd.read_csv(d / "individuals.csv")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads child processes from /proc")
@pytest.mark.parametrize("how", ["sigterm", "interrupt in the result loop"])
def test_an_interrupted_run_stops_its_workers_and_the_rerun_gives_the_same_rows(tmp_path, monkeypatch, how,
                                                                                 two_rep_reference):
    ck = tmp_path / "checkpoints"
    parallel = compose("experiment.quick.repetitions=2", "experiment.engine.n_jobs=2")
    if how == "sigterm":  # once the first task is on disk, as `kill -TERM <pid>` would
        def terminate():
            deadline = time.monotonic() + 120
            while not any(ck.glob("exp5_rep*.pt")) and time.monotonic() < deadline:
                time.sleep(0.01)
            os.kill(os.getpid(), signal.SIGTERM)

        threading.Thread(target=terminate, daemon=True).start()
        with pytest.raises(SystemExit) as ex:
            friendly_errors(R.evaluate)(parallel, out_dir=tmp_path)
        assert ex.value.code == 130
    else:  # the interrupt lands while the main process handles the first result
        import tqdm.auto

        class Bar(tqdm.auto.tqdm):
            def update(self, n=1):
                raise KeyboardInterrupt

        monkeypatch.setattr(tqdm.auto, "tqdm", Bar)
        # the caught exception keeps train's frame alive: the workers must not wait for its
        # Parallel generator to be garbage-collected
        with pytest.raises(KeyboardInterrupt) as ex:
            R.evaluate(parallel, out_dir=tmp_path)
        monkeypatch.undo()
    deadline = time.monotonic() + 3
    while _loky_workers() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _loky_workers() == [] and ex.value is not None
    kept = sorted(ck.glob("exp5_rep*.pt"))
    assert 1 <= len(kept) < 4 and not list(ck.glob("*.tmp"))
    again = R.evaluate(compose("experiment.quick.repetitions=2"), out_dir=tmp_path)
    assert again["cost"]["tasks_read_back"] == len(kept)
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "individuals.csv"), two_rep_reference)


# ---------------------------------------------------------------------------------- pooling broken runs
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    R.evaluate(compose(), out_dir=d)
    return d


def _cut_rows(text: str) -> str:
    return "".join(text.splitlines(keepends=True)[:-3])


@pytest.mark.parametrize("damage, why", [
    (lambda text: text.splitlines(keepends=True)[0], "no rows (header only)"),
    (_cut_rows, "rows, but summary.json counts"),
    (lambda text: text[:-20], "cut short"),
    (lambda text: text.replace(",reactive,", ",planning,", 1), "group hp1 2 behind"),
    (lambda text: text.replace(",far,", ",behind,"), "rows, success rate"),
    (b"\x80PK\x03\x04 binary\x00\xff\n", "not a readable CSV file"),
    ("", "empty file"),
], ids=["header only", "rows cut", "last line cut", "group changed", "situation changed", "not CSV", "empty"])
def test_pool_refuses_rows_that_do_not_match_the_summary(tmp_path, capsys, finished_run, damage, why):
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    csv = run / "individuals.csv"
    if isinstance(damage, bytes):
        csv.write_bytes(damage)
    else:
        csv.write_text(damage if isinstance(damage, str) else damage(csv.read_text()))
    with pytest.raises(SystemExit) as ex:
        friendly_errors(pool.main)([str(run)])
    assert ex.value.code == 2
    err = one_error_line(capsys)
    assert err.startswith(f"error: {csv}: ") and why in err


def test_pool_accepts_a_whole_run_and_refuses_one_without_its_summary(tmp_path, capsys, finished_run):
    summary, df = exp5_pool.pool([finished_run])
    assert len(df) == sum(g["n"] for g in summary["groups"]) == 2 * 2 * 4
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    (run / "summary.json").unlink()
    with pytest.raises(UserInputError, match="no summary.json"):
        exp5_pool.pool([run])
    (run / "summary.json").write_text("{not json")
    with pytest.raises(UserInputError, match="summary.json: cannot read its groups"):
        exp5_pool.pool([run])
