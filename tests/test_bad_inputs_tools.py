"""Every command line of the package takes its arguments as ``evaluate.py`` takes its settings
(neuroimagery/core/arguments.py): one ``error:`` line naming the option, exit status 2, no argparse
usage text, no traceback, before any work; counts within declared bounds, sizes past a limit only
with ``--allow-large``, seeds >= 0, no empty path. The tools run in-process with their work
replaced by a function that fails the test if it is reached.

The other tables of bad inputs: ``test_bad_inputs.py`` (checkpoints, run directories, pool),
``test_bad_inputs_babble.py``, ``test_bad_inputs_settings.py``, ``test_bad_inputs_overrides.py``,
``test_bad_inputs_environment.py``, ``test_bad_inputs_stored_runs.py``.
"""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from neuroimagery.app import cli, pool, stimuli
from neuroimagery.core.arguments import run_tool
from neuroimagery.experiments.exp5 import calibrate as exp5_calibrate, world as exp5_world
from neuroimagery.robot import babble, posture_fit, reach, scene_check

from support_bad_inputs import refused

ROOT = Path(__file__).resolve().parents[1]
MANY_JOBS = "100000"  # more worker processes than any machine's cores


def _forbid(monkeypatch, module, *names):
    def no_work(*a, **k):
        raise AssertionError("work started before the arguments were checked")

    for n in names:
        monkeypatch.setattr(module, n, no_work)


def _bench(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


WORLD = [  # python -m neuroimagery.experiments.exp5.world
    (["--seed", "-1"], "--seed", "a seed must be >= 0, got -1"),
    (["--seed", "0.5"], "--seed", "not a whole number"),
    (["--libraries", "1e9"], "--libraries 1000000000", "--allow-large"),
    (["--jobs", MANY_JOBS], "--jobs 100000", "core(s)"),
    (["--seed", *map(str, range(101))], "the number of seeds", "--allow-large"),
    (["--seed", "3", "3"], "--seed: each seed once", None),
    (["--libraries", "-2"], "--libraries must be >= 1", None),
]


@pytest.mark.parametrize("args,needle,also", WORLD, ids=[" ".join(a)[:30] for a, _, _ in WORLD])
def test_exp5_world_arguments(tmp_path, capsys, monkeypatch, args, needle, also):
    _forbid(monkeypatch, exp5_world, "_one_library", "run_pieces")
    refused(capsys, lambda: exp5_world.main([*args, "--out", str(tmp_path / "o")]), needle, *([also] if also else []))
    assert not (tmp_path / "o").exists()


CALIBRATE = [  # python -m neuroimagery.experiments.exp5.calibrate
    (["--trials", "-1"], "--trials must be >= 1", None),
    (["--sampler-seed", "-3"], "--sampler-seed", "a seed must be >= 0, got -3"),
    (["--babble", "1e9"], "--babble 1000000000", "--allow-large"),
    (["--trials", "1e6"], "--trials 1000000", "--allow-large"),
    (["--stage", "nowhere"], "--stage", "invalid choice"),
    (["--stag", "report"], "unrecognized arguments", None),
]


@pytest.mark.parametrize("args,needle,also", CALIBRATE, ids=[" ".join(a)[:30] for a, _, _ in CALIBRATE])
def test_exp5_calibrate_arguments(tmp_path, capsys, monkeypatch, args, needle, also):
    _forbid(monkeypatch, exp5_calibrate, "run", "open_study")
    journal = tmp_path / "j" / "search.journal"
    refused(capsys, lambda: exp5_calibrate.main(["--storage", str(journal), *args]), needle, *([also] if also else []))
    assert not (tmp_path / "j").exists()


def test_exp5_calibrate_refuses_an_empty_storage_path(capsys, monkeypatch):
    _forbid(monkeypatch, exp5_calibrate, "run", "open_study")
    refused(capsys, lambda: exp5_calibrate.main(["--storage", ""]), "--storage", "empty path")


@pytest.mark.parametrize("tool", ["world", "babble"])
def test_an_empty_output_path_is_refused(capsys, monkeypatch, tool):
    """``--out ''`` (an unset shell variable) is refused, not read as the current folder."""
    _forbid(monkeypatch, exp5_world, "_one_library", "run_pieces")
    _forbid(monkeypatch, babble, "measure")
    main = exp5_world.main if tool == "world" else babble.main
    refused(capsys, lambda: main(["--out", ""]), "--out", "empty path")


BABBLE = [
    (["--jobs", MANY_JOBS], "--jobs 100000", "--allow-large"),
    (["--jobs", "-1"], "--jobs must be >= 1", None),
    (["--seeds", "-1"], "--seeds must be >= 1", None),
    (["--rollouts", "1e3", "--roll", "5"], "unrecognized arguments: --roll", None),  # no guessed abbreviation
]


@pytest.mark.parametrize("args,needle,also", BABBLE, ids=[" ".join(a) for a, _, _ in BABBLE])
def test_babble_arguments(tmp_path, capsys, monkeypatch, args, needle, also):
    _forbid(monkeypatch, babble, "measure")
    refused(capsys, lambda: babble.main([*args, "--out", str(tmp_path / "o")]), needle, *([also] if also else []))


POOL = [
    ([], "the following arguments are required: runs"),
    (["RUN", "--bogus"], "unrecognized arguments: --bogus"),
    ([""], "argument runs: an empty path"),
    (["RUN", "--out", ""], "argument --out: an empty path"),
    (["RUN", "--ou", "x"], "unrecognized arguments: --ou"),
]


@pytest.mark.parametrize("args,needle", POOL, ids=[" ".join(a) or "nothing" for a, _ in POOL])
def test_pool_arguments(tmp_path, capsys, monkeypatch, args, needle):
    _forbid(monkeypatch, pool, "pool", "write")
    argv = [str(tmp_path) if a == "RUN" else a for a in args]
    refused(capsys, lambda: cli.friendly_errors(pool.main)(argv), needle)


def test_pool_as_a_module_prints_one_line_not_argparse_usage():
    p = subprocess.run([sys.executable, "-m", "neuroimagery.app.pool"], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert p.returncode == 2, p.stderr
    assert p.stderr.splitlines() == ["error: the following arguments are required: runs"], p.stderr


STIMULI = [
    (["exp4-A", "--size", "4"], "--size must be >= 8, got 4"),
    (["exp4-A", "--size", "1e6"], "--size 1000000: at most 1024 without --allow-large"),
    (["exp4-A", "--size", "abc"], "not a whole number: 'abc'"),
    (["exp4-A", "--out", ""], "--out: an empty path"),
    ([""], "argument set: an empty path"),
    (["exp4-A", "--like", "exp4-B"], "--like has no effect without --measure"),
    (["--measure", "--markdown", "--size", "0"], "--size must be >= 8"),
    (["exp4-A", "--bogus"], "unrecognized arguments: --bogus"),
]


@pytest.mark.parametrize("args,needle", STIMULI, ids=[" ".join(a) or "empty" for a, _ in STIMULI])
def test_stimuli_arguments(tmp_path, capsys, monkeypatch, args, needle):
    _forbid(monkeypatch, stimuli, "contact_sheet", "_measure")
    refused(capsys, lambda: stimuli.main(args), needle)


REACH = [
    (["--samples", "0"], "--samples must be >= 1"),
    (["--samples", "1e9"], "--samples 1000000000: at most 10000000 without --allow-large"),
    (["--seed", "-3"], "a seed must be >= 0, got -3"),
    (["--samples", "nan"], "not a whole number: 'nan'"),
]


@pytest.mark.parametrize("args,needle", REACH, ids=[" ".join(a) for a, _ in REACH])
def test_reach_arguments(capsys, monkeypatch, args, needle):
    _forbid(monkeypatch, reach, "compute_frontier")
    refused(capsys, lambda: reach.main(args), needle)


@pytest.mark.parametrize("module", [posture_fit, scene_check], ids=["posture_fit", "scene_check"])
def test_tools_without_options_refuse_one(capsys, monkeypatch, module):
    _forbid(monkeypatch, module, "fit_posture" if module is posture_fit else "scene_geometry")
    refused(capsys, lambda: module.main(["--fast"]), "unrecognized arguments: --fast")


BENCHMARKS = [  # the benchmarks the docs tell a user to run
    ("bench_command", ["nope"], "invalid choice: 'nope'"),
    ("bench_command", ["exp4", "--repeat", "0"], "--repeat must be in [1, 100], got 0"),
    ("bench_threads", ["--experiment", "exp9"], "invalid choice: 'exp9'"),
    ("bench_robot", ["--quick"], "unrecognized arguments: --quick"),
    ("exp5_choice", [""], "an empty path"),
    ("exp5_choice", ["nowhere"], "nowhere has no individuals.csv"),
    ("physics_step", ["--rollouts-per-posture", "0"], "--rollouts-per-posture must be >= 1"),
    ("bench_exp5", ["--seed", "-1"], "a seed must be >= 0"),
    ("bench_exp5", ["--repetitions", "1e4"], "--repetitions 10000: at most 100 without --allow-large"),
]


@pytest.mark.parametrize("name,args,needle", BENCHMARKS, ids=[f"{n} {' '.join(a)}" for n, a, _ in BENCHMARKS])
def test_benchmark_arguments(capsys, name, args, needle):
    mod = _bench(name)
    refused(capsys, lambda: run_tool(mod.main, args), needle)
