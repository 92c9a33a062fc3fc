"""SIGKILL at each phase of Experiment 4 (``preset=quick``, one participant): during training,
in the middle of the checkpoint write, during the tests, in the middle of a figure (a rerun into a
finished directory). Each killed run is then run again into its directory: no temporary file is
left, no file is empty or cut, every figure decodes, and ``trials.csv`` is identical to that of a
run never killed. The kill is made at a known point by the process itself (``os.kill(getpid(),
SIGKILL)`` from a patched function), so the test is the same on every machine.

Slow (about ten Exp. 4 quick runs): ``pytest -m slow tests/test_kill_runs.py``.
"""
import json
import signal
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ARGS = ["experiment=exp4", "preset=quick", "participants=1", "progress=false", "logger=tensorboard"]

# code run before evaluate.py: the patch that kills the process at one phase
KILL = {
    # during training: when the posture maps start, after the forward models were trained
    "training": """
import neuroimagery.experiments.chapter6.protocol as pc
pc.train_posture_maps = lambda *a, **k: die()
""",
    # in the middle of the checkpoint write: half the bytes are in the temporary file
    "checkpoint write": """
import neuroimagery.app.run as r
def half(obj, path):
    import io, torch
    buf = io.BytesIO(); torch.save(obj, buf)
    with open(path, 'wb') as f:
        f.write(buf.getvalue()[: len(buf.getvalue()) // 2]); f.flush()
    die()
r.torch_save = half
""",
    # during the tests: after the first block of trials was counted
    "tests": """
import neuroimagery.core.progress as p
p.advance = lambda *a, **k: die()
""",
    # in the middle of the first figure of a rerun into a finished directory
    "figures": """
import neuroimagery.analysis.figures as fg
from neuroimagery.core.files import tmp_path
def cut(fig, path, **kw):
    with open(tmp_path(path), 'wb') as f:
        f.write(b'\\x89PNG'); f.flush()
    die()
fg.save_figure = cut
""",
}
PRELUDE = """
import os, signal, sys, runpy
def die():
    os.kill(os.getpid(), signal.SIGKILL)
"""


def _evaluate(run_dir: Path, patch: str = "") -> subprocess.CompletedProcess:
    code = PRELUDE + patch + (f"\nsys.argv = ['evaluate.py', *{ARGS!r}, 'hydra.run.dir={run_dir}']\n"
                              f"runpy.run_path({str(ROOT / 'evaluate.py')!r}, run_name='__main__')\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=1200)


def _check_whole(d: Path) -> None:
    tmp = [p for p in d.rglob("*.tmp")]
    assert not tmp, tmp
    empty = [p for p in d.rglob("*") if p.is_file() and p.stat().st_size == 0]
    assert not empty, empty
    for png in d.rglob("*.png"):
        assert mpimg.imread(png).size > 0, png  # decodes: not cut
    m = json.loads((d / "manifest.json").read_text())
    assert m["state"] == "complete", m.get("state")
    for rel in m["files"]:  # every file as the run finished it
        assert (d / rel).is_file(), rel
    assert not (d / "run.lock").exists()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("kill") / "ref"
    p = _evaluate(d)
    assert p.returncode == 0, p.stderr[-2000:]
    _check_whole(d)
    return d


@pytest.mark.slow
@pytest.mark.parametrize("phase", list(KILL))
def test_a_run_killed_at_each_phase_reruns_whole(reference, tmp_path, phase):
    d = tmp_path / "run"
    if phase == "figures":  # a finished directory, then a rerun killed while it rewrites a figure
        assert _evaluate(d).returncode == 0
        figures_before = {p.name: p.read_bytes() for p in (d / "figures").glob("*.png")}
    killed = _evaluate(d, KILL[phase])
    assert killed.returncode == -signal.SIGKILL, (killed.returncode, killed.stderr[-2000:])
    m = json.loads((d / "manifest.json").read_text())
    assert m["state"] == "running"  # what a kill leaves: pool and checkpoint= refuse it
    if phase == "checkpoint write":
        assert list((d / "checkpoints").glob("exp4.pt.*.tmp")) and not (d / "checkpoints" / "exp4.pt").exists()
    if phase == "figures":
        assert list((d / "figures").glob("*.png.*.tmp"))
        assert {p.name: p.read_bytes() for p in (d / "figures").glob("*.png")} == figures_before  # none cut
    again = _evaluate(d)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "its lock was held by PID" in again.stderr and "which is gone" in again.stderr
    if phase in ("checkpoint write", "figures"):
        assert "temporary file(s) that a killed run left" in again.stderr
    _check_whole(d)
    assert (d / "trials.csv").read_bytes() == (reference / "trials.csv").read_bytes()
