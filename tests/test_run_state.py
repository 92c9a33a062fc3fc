"""A run's state in ``manifest.json`` (``running`` / ``complete`` / ``interrupted``), the lock of a
directory being written, and what a refusal leaves (nothing): ``pool`` and ``checkpoint=`` take
only complete runs; a run written before the state existed is taken with one ``note:``."""
import json
import logging
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import make_cfg
from support_experiments import patch_experiment

from neuroimagery.app import cli, pool

from neuroimagery.core import lock
from neuroimagery.experiments.demo import protocol as demo
from neuroimagery.app.run import evaluate, train

ROOT = Path(__file__).resolve().parents[1]


def _demo(*over):
    return make_cfg("experiment=demo", "participants=2", "progress=false", "logger=none", *over)


def _refused(capsys, fn, *args, **kwargs) -> str:
    with pytest.raises(SystemExit) as ex:
        fn(*args, **kwargs)
    err = capsys.readouterr().err
    assert ex.value.code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    return lines[0]


def _manifest(d: Path) -> dict:
    return json.loads((d / "manifest.json").read_text())


def _pool(*dirs):
    return cli.friendly_errors(pool.main)([str(d) for d in dirs])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("state")
    for s in (0, 1):
        evaluate(_demo(f"seed={s}"), out_dir=root / f"s{s}")
    return root


def test_a_finished_run_is_complete_with_the_hashes_of_its_files(runs):
    m = _manifest(runs / "s0")
    assert m["state"] == "complete" and m["trained"] is True and "stopped" not in m
    assert {"trials.csv", "summary.json", "report.md", "checkpoints/model.pt"} <= set(m["files"])
    assert not (runs / "s0" / "run.lock").exists()


def _interrupt_in(monkeypatch, where: str):
    def stop(*a, **k):
        raise KeyboardInterrupt

    patch_experiment(monkeypatch, "demo", **{where: stop})


@pytest.mark.parametrize("where,trained", [("train", False), ("evaluate", True)])
def test_an_interrupted_overwrite_is_refused_by_pool(runs, tmp_path, monkeypatch, capsys, where, trained):
    d = tmp_path / "over"
    evaluate(_demo("seed=1"), out_dir=d)  # an earlier run with 2 participants
    _interrupt_in(monkeypatch, where)
    with pytest.raises(SystemExit) as ex:  # SIGTERM and Ctrl-C both arrive as KeyboardInterrupt
        cli.friendly_errors(evaluate)(_demo("seed=1", "participants=3", "overwrite=true"), out_dir=d)
    assert ex.value.code == 130
    monkeypatch.undo()
    m = _manifest(d)
    assert m["participants"] == 3 and m["state"] == "interrupted" and m["trained"] is trained
    assert "interrupted (Ctrl-C or SIGTERM)" in m["stopped"]
    assert not (d / "run.lock").exists()
    capsys.readouterr()
    line = _refused(capsys, _pool, runs / "s0", d)
    assert f"pool: {d} is not a complete run: interrupted" in line
    ck = cli.friendly_errors(evaluate)
    if not trained:  # its checkpoints are the earlier run's: refused
        line = _refused(capsys, ck, _demo(f"checkpoint={d}", "participants=3", "seed=1"), out_dir=tmp_path / "ev")
        assert f"checkpoint: {d} is not a complete run: interrupted" in line
        assert not (tmp_path / "ev").exists()


def test_a_killed_run_is_refused_as_stopped_and_a_live_one_as_being_written(runs, tmp_path, capsys):
    d = tmp_path / "killed"
    evaluate(_demo("seed=1"), out_dir=d)
    m = {**_manifest(d), "state": "running", "trained": False}
    (d / "manifest.json").write_text(json.dumps(m))
    line = _refused(capsys, _pool, runs / "s0", d)
    assert "not a complete run: stopped before it finished (killed" in line
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (d / "run.lock").write_text(json.dumps({"host": socket.gethostname(), "pid": live.pid}))
        line = _refused(capsys, _pool, runs / "s0", d)
        assert f"still being written (host {socket.gethostname()}, PID {live.pid})" in line
        # a second run into that directory is refused, naming the holder
        line = _refused(capsys, cli.friendly_errors(evaluate), _demo("seed=1"), out_dir=d)
        assert f"{d} is being written by another run (host {socket.gethostname()}, PID {live.pid}" in line
    finally:
        live.kill()
        live.wait()
    # its process gone: the lock is taken over with a note, and the run completes
    evaluate(_demo("seed=1"), out_dir=d)
    err = capsys.readouterr().err
    assert f"note: {d}: its lock was held by PID {live.pid} on this host, which is gone" in err
    assert _manifest(d)["state"] == "complete" and not (d / "run.lock").exists()


def test_a_lock_of_another_host_is_refused_naming_it(tmp_path, capsys):
    d = tmp_path / "remote"
    d.mkdir()
    (d / "run.lock").write_text(json.dumps({"host": "node-17.cluster", "pid": 4242}))
    line = _refused(capsys, cli.friendly_errors(evaluate), _demo(), out_dir=d)
    assert "locked by a run on host node-17.cluster, PID 4242" in line
    assert sorted(p.name for p in d.iterdir()) == ["run.lock"]  # nothing claimed


def test_the_lock_is_held_while_the_run_works(tmp_path, monkeypatch):
    seen = {}
    real = demo.evaluate

    def look(cfg, run, trained):
        seen.update(lock.read(run.root) or {})
        seen["state"] = _manifest(run.root)["state"]
        return real(cfg, run, trained)

    patch_experiment(monkeypatch, "demo", evaluate=look)
    evaluate(_demo(), out_dir=tmp_path / "r")
    assert seen["pid"] == os.getpid() and seen["host"] == socket.gethostname() and seen["state"] == "running"
    assert not (tmp_path / "r" / "run.lock").exists()


def test_a_run_written_before_the_state_is_refused_with_its_rerun_command(runs, tmp_path, capsys):
    """A manifest without ``state`` (runs of 0.x before runs recorded it) is not pooled: one line
    with the command that runs it again."""
    import shutil

    d = tmp_path / "old"
    shutil.copytree(runs / "s1", d)
    m = _manifest(d)
    for k in ("state", "trained", "files"):
        m.pop(k)
    (d / "manifest.json").write_text(json.dumps(m))
    line = _refused(capsys, _pool, runs / "s0", d)
    assert "written before runs recorded their state" in line and "python evaluate.py experiment=demo seed=1" in line


def test_a_file_changed_after_the_run_finished_is_refused(runs, tmp_path, capsys):
    import shutil

    d = tmp_path / "edited"
    shutil.copytree(runs / "s1", d)
    (d / "report.md").write_text("another report\n")
    line = _refused(capsys, _pool, runs / "s0", d)
    assert f"{d / 'report.md'}: changed since the run finished" in line


def test_a_refusal_claims_nothing(runs, tmp_path, capsys):
    fresh = tmp_path / "new" / "run"
    line = _refused(capsys, cli.friendly_errors(evaluate), _demo(f"checkpoint={tmp_path / 'none'}"), out_dir=fresh)
    assert "checkpoint:" in line and not (tmp_path / "new").exists()
    other = runs / "s0"
    before = {p: p.stat().st_mtime_ns for p in other.rglob("*")}
    line = _refused(capsys, cli.friendly_errors(evaluate), _demo("participants=3"), out_dir=other)
    assert "holds another run" in line
    assert {p: p.stat().st_mtime_ns for p in other.rglob("*")} == before  # untouched, no lock left
    # a setting refused before work: nothing made
    line = _refused(capsys, cli.friendly_errors(train), _demo("participants=0"), out_dir=fresh)
    assert "participants" in line and not fresh.exists()


def _evaluate_py(run_dir: Path, *args: str):
    return subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "experiment=demo", "logger=none",
                           "progress=false", f"hydra.run.dir={run_dir}", *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)


def test_a_refused_command_removes_the_directory_hydra_made_and_keeps_one_that_was_there(tmp_path):
    made = tmp_path / "made"
    p = _evaluate_py(made, "participants=-1")
    assert p.returncode == 2 and p.stderr.strip().startswith("error: ") and len(p.stderr.strip().splitlines()) == 1
    assert not made.exists()
    there = tmp_path / "there"
    there.mkdir()
    p = _evaluate_py(there, "participants=-1")
    assert p.returncode == 2
    assert there.is_dir() and not (there / "manifest.json").exists()


def test_a_phase_that_stops_does_not_log_done(tmp_path, monkeypatch, caplog):
    _interrupt_in(monkeypatch, "evaluate")
    with caplog.at_level(logging.INFO, logger="neuroimagery"), pytest.raises(KeyboardInterrupt):
        evaluate(_demo("progress=true"), out_dir=tmp_path / "r")
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("demo ")]
    test_lines = [ln for ln in lines if ln.startswith("demo test")]
    assert test_lines and all("done" not in ln for ln in test_lines), lines
    assert "interrupted" in test_lines[0] and "not finished" in test_lines[0]


def test_a_run_that_stopped_before_any_result_does_not_block_the_next(tmp_path, monkeypatch, capsys):
    d = tmp_path / "r"
    _interrupt_in(monkeypatch, "train")
    with pytest.raises(KeyboardInterrupt):
        evaluate(_demo("experiment.eta=0.3"), out_dir=d)
    monkeypatch.undo()
    assert _manifest(d)["state"] == "interrupted"
    capsys.readouterr()
    evaluate(_demo(), out_dir=d)  # other settings, no overwrite=true: nothing of the stopped run is lost
    assert "holds a run that stopped before it wrote any result" in capsys.readouterr().err
    assert _manifest(d)["state"] == "complete"


def test_sigterm_during_an_overwrite_leaves_it_interrupted_and_pool_refuses_it(runs, tmp_path, capsys):
    """A real SIGTERM (sent by the process to itself once testing starts, as a cluster's scheduler
    would send it) into a directory holding a finished run with other settings, overwrite=true."""
    import shutil

    d = tmp_path / "over"
    shutil.copytree(runs / "s1", d)  # the earlier run: 2 participants
    code = ("import os, signal, sys, runpy\n"
            "import dataclasses, neuroimagery.experiments.demo as demo\n"
            "demo.EXPERIMENT = dataclasses.replace(demo.EXPERIMENT, evaluate=lambda *a, **k: "
            "os.kill(os.getpid(), signal.SIGTERM) or __import__('time').sleep(30))\n"
            f"sys.argv = ['evaluate.py', 'experiment=demo', 'logger=none', 'progress=false', 'seed=1', "
            f"'participants=3', 'overwrite=true', 'hydra.run.dir={d}']\n"
            f"runpy.run_path({str(ROOT / 'evaluate.py')!r}, run_name='__main__')\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert p.returncode == 130, p.stderr
    assert p.stderr.strip().splitlines()[-1].startswith("interrupted: "), p.stderr
    assert "Traceback" not in p.stderr
    m = _manifest(d)
    assert m["participants"] == 3 and m["state"] == "interrupted" and "while testing" in m["stopped"]
    line = _refused(capsys, _pool, runs / "s0", d)
    assert f"{d} is not a complete run: interrupted" in line
    log = (d / "evaluate.log").read_text()
    assert "demo test: interrupted" in log and "demo test: done" not in log
