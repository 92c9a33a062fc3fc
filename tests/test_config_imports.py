"""The checks before any work import nothing heavy: validating a configuration of any experiment
reads the experiment's schema and checks (its light modules), never torch, the statistics or
plotting libraries, the simulator or OpenCV, so a refused setting is answered at once. Each test
runs in a fresh interpreter, where ``sys.modules`` shows what the checks imported."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "scipy", "pandas", "matplotlib", "pybullet", "cv2")

CHECKS = r"""
import json, sys
from hydra import compose, initialize_config_dir
from neuroimagery.config import EXPERIMENTS, register_configs
from neuroimagery.core.errors import UserInputError
from neuroimagery.validation import prepare

register_configs()
out = {"refused": {}, "passed": []}


def refusal(overrides):
    try:
        prepare(compose("config", overrides=overrides))
    except UserInputError as e:
        return str(e)
    return None


with initialize_config_dir(config_dir=CONF, version_base="1.3"):
    for name in EXPERIMENTS:
        out["refused"][name] = [refusal([f"experiment={name}", "participants=-3"]),  # by the schema
                                refusal([f"experiment={name}", "logger=none", "logger.map_images=false"])]  # by check_run
        if name not in FULL_CHECKS_LOAD:
            assert refusal([f"experiment={name}"]) is None  # every check of the default configuration
            out["passed"].append(name)
out["heavy"] = [m for m in HEAVY if m in sys.modules]
print(json.dumps(out))
"""
# Experiment 6's own checks render a probe view of its objects with the simulator
# (experiments/exp6/checks.py): its default configuration is checked by tests/test_exp6.py
FULL_CHECKS_LOAD = ("exp6",)


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_checks_of_every_experiment_import_nothing_heavy(tmp_path):
    prelude = f"CONF = {str(ROOT / 'conf')!r}\nHEAVY = {HEAVY!r}\nFULL_CHECKS_LOAD = {FULL_CHECKS_LOAD!r}\n"
    p = _python(prelude + CHECKS, tmp_path)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout.strip().splitlines()[-1])
    from neuroimagery.config import EXPERIMENTS

    assert sorted(out["refused"]) == sorted(EXPERIMENTS)
    for name, (schema, check) in out["refused"].items():
        assert schema is not None and "participants must be >= 1" in schema, (name, schema)
        assert check is not None and "logger.map_images=False has no effect" in check, (name, check)
    assert out["passed"] == [n for n in EXPERIMENTS if n not in FULL_CHECKS_LOAD]
    assert out["heavy"] == []


def test_a_refusal_of_evaluate_py_imports_nothing_heavy(tmp_path):
    """The entry point itself: one ``error:`` line, exit status 2, before the run's imports."""
    code = (f"import atexit, runpy, sys\n"
            f"atexit.register(lambda: print('heavy:', [m for m in {HEAVY!r} if m in sys.modules]))\n"
            f"sys.argv = ['evaluate.py', 'experiment=exp4', 'participants=-3', 'hydra.run.dir={tmp_path / 'run'}']\n"
            f"runpy.run_path({str(ROOT / 'evaluate.py')!r}, run_name='__main__')\n")
    p = _python(code, tmp_path)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip().splitlines() == ["error: invalid configuration: participants must be >= 1, got -3"]
    assert p.stdout.strip().splitlines()[-1] == "heavy: []"
    assert not (tmp_path / "run").exists()
