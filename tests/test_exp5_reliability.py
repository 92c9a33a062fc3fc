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

import neuroimagery.run as R  # noqa: E402
from neuroimagery.cli import friendly_errors  # noqa: E402
from neuroimagery.errors import UserInputError  # noqa: E402
from neuroimagery.experiments import exp5, exp5_pool, exp5_tasks  # noqa: E402

STANDIN = "support_tool_env:StandInToolEnv"
ARGS = ("preset=quick", f"experiment.environment={STANDIN}", "experiment.n_jobs=1",
        "experiment.quick_repetitions=1", "experiment.max_epochs=2", "experiment.explore_max_rollouts=120",
        "experiment.hp1_levels=[2,6]", "experiment.hp1_ages=[14,22]", "experiment.hp2_trials=[0,4]",
        "experiment.hp2_ages=[14,16]", "logger=none", "progress=false")


def compose(*overrides):
    return make_cfg("experiment=exp5", *ARGS, *overrides)


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


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
    plant(planted, marker)
    extra = {"resumed run": (), "reuse_libraries": (f"experiment.reuse_libraries={other}",),
             "checkpoint": (f"checkpoint={other}",)}[where]
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
    path.parent.mkdir(parents=True)
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
    full = exp5_tasks.tmp_path(second)  # where this process writes the second task: a full disk
    full.parent.mkdir(parents=True)
    full.symlink_to("/dev/full")
    with pytest.raises(SystemExit) as ex:
        friendly_errors(R.evaluate)(compose(), out_dir=tmp_path)
    assert ex.value.code == 2
    assert one_error_line(capsys) == f"error: cannot write {second}: No space left on device\n"
    assert exp5_tasks.read_task(first)["task"]["key"] == "rep000_behind" and not second.exists()
    assert not list((tmp_path / "checkpoints").glob("*.tmp"))  # the temporary name is cleared
