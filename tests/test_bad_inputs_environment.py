"""Faults of the environment, and refused runs that must leave other runs as they were.

A run refused because its directory holds another run, or is locked by a live one, writes nothing
there (no lock, no temporary file, no line in that run's job log: the log is written only once the
run has claimed its directory, ``console.RunLogHandler``). A run directory that cannot be written
and a HOME that cannot be written are one ``error:`` line like any other refusal (no traceback of
Hydra's log handler, no matplotlib warning before it).
"""
from __future__ import annotations

import json
import logging
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from neuroimagery.core import console

from support_bad_inputs import evaluating, refused

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    from neuroimagery.app.run import evaluate

    from conftest import make_cfg

    d = tmp_path_factory.mktemp("env") / "run"
    evaluate(make_cfg("experiment=demo", "participants=2", "logger=none"), out_dir=d)
    (d / "evaluate.log").write_text("[the run's own job log]\n")
    return d


def _snapshot(d: Path) -> dict:
    """Every path under ``d`` with its bytes and modification time, and ``d``'s own."""
    out = {".": d.stat().st_mtime_ns}
    for p in sorted(d.rglob("*")):
        out[str(p.relative_to(d))] = (p.read_bytes() if p.is_file() else None, p.stat().st_mtime_ns)
    return out


def test_a_run_refused_for_another_run_s_directory_writes_nothing_there(demo_run, tmp_path, capsys):
    d = tmp_path / "run"
    shutil.copytree(demo_run, d)
    before = _snapshot(d)
    refused(capsys, evaluating(d, "experiment=demo", "participants=3", "logger=none"), "holds another run")
    assert _snapshot(d) == before


def test_a_run_refused_for_a_live_lock_writes_nothing_there(demo_run, tmp_path, capsys):
    d = tmp_path / "run"
    shutil.copytree(demo_run, d)
    (d / "run.lock").write_text(json.dumps({"host": socket.gethostname(), "pid": os.getpid(), "started": None}))
    before = _snapshot(d)
    refused(capsys, evaluating(d, "experiment=demo", "participants=2", "logger=none"), "being written by another run")
    assert _snapshot(d) == before


def _log_records(path: Path):
    handler = console.RunLogHandler(str(path))
    handler.setFormatter(logging.Formatter("%(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    level, root.level = root.level, logging.INFO
    return handler, lambda: (root.removeHandler(handler), handler.close(), setattr(root, "level", level))


def test_the_job_log_is_written_only_once_the_run_claims_its_directory(tmp_path):
    log = tmp_path / "a" / "evaluate.log"
    log.parent.mkdir()
    handler, done = _log_records(log)
    try:
        console.note("before the claim")
        assert not log.exists()  # nothing opened, nothing written
        console.claimed(tmp_path / "b")  # another directory: still nothing
        assert not log.exists()
        console.claimed(tmp_path / "a")
        console.note("after the claim")
        handler.flush()
        assert log.read_text().splitlines() == ["note: before the claim", "note: after the claim"]
    finally:
        done()


def test_a_refused_run_drops_its_job_log(tmp_path, capsys):
    log = tmp_path / "evaluate.log"
    handler, done = _log_records(log)
    try:
        console.error("refused")
    finally:
        done()
    assert not log.exists() and not list(tmp_path.iterdir())


def _evaluate_py(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "experiment=demo", "logger=none", *args],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)


def _one_error_line(p: subprocess.CompletedProcess, *needles: str) -> str:
    assert p.returncode == 2, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), p.stderr
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def test_a_run_directory_that_cannot_be_written_is_one_line(tmp_path):
    if os.geteuid() == 0:  # permissions do not bind root; /proc/self cannot be written by anyone
        d = "/proc/self"
    else:
        d = tmp_path / "ro"
        d.mkdir()
        d.chmod(0o555)
    p = _evaluate_py("participants=2", f"hydra.run.dir={d}")
    _one_error_line(p, f"cannot write into the run directory {d}")


def test_an_unwritable_home_puts_nothing_before_the_error_line(tmp_path):
    home = tmp_path / "home"
    home.write_text("a file where HOME should be a folder")
    env = {k: v for k, v in os.environ.items() if k not in ("MPLCONFIGDIR", "XDG_CONFIG_HOME", "XDG_CACHE_HOME")}
    p = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "experiment=demo", "seed=-1",
                        f"hydra.run.dir={tmp_path / 'r'}"], capture_output=True,
                       text=True, cwd=ROOT, timeout=120, env={**env, "HOME": str(home)})
    _one_error_line(p, "seed must be")
