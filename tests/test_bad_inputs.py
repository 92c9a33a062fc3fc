"""Malformed inputs across the five experiments, stimulus folders, checkpoints, run directories and
the pooling tool: each is refused with one ``error:`` line naming the culprit, exit status 2, no
traceback, within seconds and before any training starts.

The cases run in-process through the same wrappers the command line uses (``friendly_errors`` for a
run, the patched Hydra reporter for composition errors), so the table costs the suite little time;
two cases go through ``train.py`` itself.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from neuroimagery import cli
from neuroimagery.run import evaluate, train

from conftest import make_cfg

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ("exp1", "exp2", "exp3", "exp4", "exp5", "exp6", "demo")
LIMIT_S = 10.0  # a refusal must come within seconds: these are checks, not work


class _Marker:
    """A pickle that would create a file if it were ever unpickled unsafely."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


@pytest.fixture
def no_training(monkeypatch):
    """Any experiment that starts training fails the test: refusals must come first."""
    import importlib

    def forbidden(*a, **k):
        raise AssertionError("training started before the input was refused")

    for name in EXPERIMENTS:
        monkeypatch.setattr(importlib.import_module(f"neuroimagery.experiments.{name}"), "train", forbidden)


def _refused(capsys, fn, *needles):
    """Run ``fn`` as the command line would; assert one clear ``error:`` line naming ``needles``."""
    t0 = time.perf_counter()
    with pytest.raises(SystemExit) as ex:
        fn()
    took = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert ex.value.code == 2, err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert took < LIMIT_S, f"refused after {took:.1f} s"
    return lines[0]


def _evaluate(tmp, *over):
    return lambda: cli.friendly_errors(evaluate)(make_cfg(*over), out_dir=tmp)


def _train(tmp, *over):
    return lambda: cli.friendly_errors(train)(make_cfg(*over), out_dir=tmp)


CONFIG_CASES = [
    # numbers that are not finite, or out of range
    (["experiment=exp4", "experiment.noise_amplitude=inf"], "experiment.noise_amplitude"),
    (["experiment=exp2", "experiment.proprio_gain=nan"], "experiment.proprio_gain"),
    (["experiment=exp1", "experiment.hebb_eta=nan"], "experiment.hebb_eta"),
    (["experiment=exp3", "experiment.m1_centre_sigma=inf"], "experiment.m1_centre_sigma"),
    (["experiment=exp5", "experiment.brain.eta=nan"], "experiment.brain.eta"),
    (["experiment=demo", "experiment.noise=inf"], "experiment.noise"),
    (["experiment=exp4", "vision.gamma=nan"], "vision.gamma"),
    (["experiment=exp4", "experiment.ppc_angles=[0,nan]"], "experiment.ppc_angles"),
    (["experiment=exp5", "experiment.acquisition.explore_patience=0"], "experiment.acquisition.explore_patience"),
    (["experiment=exp1", "participants=0"], "participants"),
    (["experiment=exp3", "seed=-1"], "seed"),
    (["experiment=exp4", "preset=huge"], "preset"),
    (["experiment=exp2", "threads=-2"], "threads"),
    (["experiment=exp5", "experiment.engine.n_jobs=0"], "experiment.engine.n_jobs"),
    (["experiment=exp4", "experiment.flip_axis=diagonal"], "experiment.flip_axis"),
    (["experiment=exp3", "experiment.m1_readout=middle"], "experiment.m1_readout"),
    (["experiment=exp5", "experiment.situations=[nowhere]"], "experiment.situations"),
    (["experiment=exp4", "logger.kind=wandb"], "logger.kind"),
    (["experiment=exp1", "vision.kind=laser"], "vision.kind"),
    (["experiment=demo", "+experiment.stp_deg=3"], "experiment.stp_deg"),
    (["experiment=exp2", "+experiment.som_eta=0.2"], "it is experiment.som.eta now"),  # an old key added with +
    (["experiment=exp1", "experiment.field.tau=0"], "experiment.field.tau"),  # a group's own range check
    (["experiment=exp4", "experiment.fm.batch=0"], "experiment.fm.batch"),
    # keys that would have no effect in this experiment or with these options
    (["experiment=exp4", "vision.size=16"], "vision.size"),
    (["experiment=exp1", "vision.gaze_jitter_deg=1"], "vision.gaze_jitter_deg"),
    (["experiment=exp4", "stimuli.path=/tmp"], "stimuli.path"),
    (["experiment=exp5", "participants=3"], "participants"),
    (["experiment=exp5", "vision.noise_std=5"], "vision.noise_std"),
    (["experiment=demo", "stimuli=folder", "stimuli.path=/tmp"], "stimuli.kind"),
    (["experiment=exp4", "logger=none", "logger.map_images=false"], "logger.map_images"),
    (["experiment=exp3", "experiment.quick.objects=2"], "experiment.quick.objects"),
    (["experiment=exp4", "preset=quick", "experiment.fm.images=100"], "experiment.fm.images"),
    (["experiment=exp3", "experiment.m1_sigma=0.3"], "experiment.m1_sigma"),  # not read with the default m1_readout=centre
    (["experiment=exp4", "experiment.noise_tests=[]", "experiment.noise_amplitude=0.3"], "experiment.noise_amplitude"),
    (["experiment=exp5", "preset=quick", "experiment.repetitions=5"], "experiment.repetitions"),
    (["experiment=exp2", "threads=1", "experiment.auto_threads=2"], "experiment.auto_threads"),
]


@pytest.mark.parametrize("over,needle", CONFIG_CASES, ids=[" ".join(o) for o, _ in CONFIG_CASES])
def test_bad_settings_are_refused_before_any_work(tmp_path, capsys, no_training, over, needle):
    _refused(capsys, _evaluate(tmp_path / "run", *over), needle)
    assert not (tmp_path / "run").exists()  # nothing written


def test_checkpoint_is_refused_in_training(tmp_path, capsys, no_training):
    _refused(capsys, _train(tmp_path / "run", "experiment=demo", f"checkpoint={tmp_path}"), "checkpoint=")


@pytest.mark.parametrize("over,needle", [(["experiment=demo", "experiment.stp_deg=3"], "stp_deg"),
                                         (["experiment=demo", "seed=abc"], "seed"),
                                         # a key that moved into a group is refused with its new place
                                         (["experiment=exp1", "experiment.field_tau=5"], "it is experiment.field.tau now"),
                                         (["experiment=exp2", "experiment.cluster_sigma=2"], "experiment.som.cluster_sigma"),
                                         (["experiment=exp3", "experiment.quick_fm_images=9"], "experiment.quick.fm_images"),
                                         (["experiment=exp4", "experiment.eta_posture=0.2"], "experiment.posture.eta")])
def test_hydra_composition_errors_are_one_line(monkeypatch, capsys, over, needle):
    from hydra._internal import utils as hydra_utils

    monkeypatch.setattr(hydra_utils, "run_and_report", hydra_utils.run_and_report)  # restored afterwards
    cli.plain_hydra_errors()
    _refused(capsys, lambda: hydra_utils.run_and_report(lambda: make_cfg(*over)), needle)


# ------------------------------------------------------------------------ stimulus folders
def _png(path, image):
    assert cv2.imwrite(str(path), image)


def _shape_image(w=64, h=64):
    img = np.full((h, w, 3), 255, np.uint8)
    img[h // 4: h // 2, w // 4: 3 * w // 4] = (0, 0, 200)
    return img


def _folder(tmp_path, kind):
    d = tmp_path / f"stim_{kind}"
    d.mkdir()
    if kind == "corrupt":
        (d / "a.png").write_bytes(os.urandom(300))
    elif kind == "blank":
        _png(d / "a.png", np.full((64, 64, 3), 255, np.uint8))
    elif kind == "huge":
        _png(d / "a.png", _shape_image(4097, 8))
    elif kind == "one":
        _png(d / "a.png", _shape_image())
    elif kind == "file":
        d.rmdir()
        d.write_text("not a folder")
    return d


@pytest.mark.parametrize("exp,kind,needle", [
    ("exp4", "empty", "no PNG or JPEG"), ("exp3", "corrupt", "a.png"), ("exp4", "blank", "no shape found"),
    ("exp3", "huge", "4097 x 8"), ("exp1", "one", "at least 2"), ("exp2", "file", "not a folder"),
    ("exp4", "missing", "not a folder")])
def test_bad_stimulus_folders_are_refused_before_training(tmp_path, capsys, no_training, exp, kind, needle):
    d = tmp_path / "nowhere" if kind == "missing" else _folder(tmp_path, kind)
    _refused(capsys, _evaluate(tmp_path / "run", f"experiment={exp}", "stimuli=folder", f"stimuli.path={d}"), needle)


# ------------------------------------------------------------------------------ checkpoints
@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("demo") / "train"
    train(make_cfg("experiment=demo", "participants=2"), out_dir=d)
    return d


def _copy_run(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_a_crafted_checkpoint_runs_nothing(tmp_path, capsys, demo_run):
    ck = _copy_run(demo_run, tmp_path / "ck")
    marker = tmp_path / "executed"
    with open(ck / "checkpoints" / "model.pt", "wb") as f:
        pickle.dump({"state_dict": _Marker(marker)}, f)
    _refused(capsys, _evaluate(tmp_path / "run", "experiment=demo", "participants=2", f"checkpoint={ck}"),
             "model.pt", "nothing in it was run")
    assert not marker.exists()
    torch.save({"state_dict": _Marker(marker)}, ck / "checkpoints" / "model.pt")  # the zip format too
    _refused(capsys, _evaluate(tmp_path / "run", "experiment=demo", "participants=2", f"checkpoint={ck}"), "model.pt")
    assert not marker.exists()


def _alter(path: Path, how: str) -> None:
    if how == "truncated":
        path.write_bytes(path.read_bytes()[:100])
    elif how == "tensors":
        state = torch.load(path, weights_only=True)
        state["state_dict"] = {k: v + 1 if v.is_floating_point() else v for k, v in state["state_dict"].items()}
        torch.save(state, path)
    elif how == "no manifest":
        state = torch.load(path, weights_only=True)
        state.pop("manifest")
        torch.save(state, path)


@pytest.mark.parametrize("how,over,needle", [
    ("truncated", [], "corrupt"),
    ("tensors", [], "hash"),
    ("no manifest", [], "no manifest"),
    ("", ["experiment.eta=0.3"], "experiment.eta 0.2 (stored) vs 0.3"),
    ("", ["participants=3"], "participants 2 (stored) vs 3"),
    ("", ["seed=5"], "seed 0 (stored) vs 5"),
])
def test_bad_or_mismatched_checkpoints_are_refused(tmp_path, capsys, no_training, demo_run, how, over, needle):
    ck = _copy_run(demo_run, tmp_path / "ck")
    if how:
        _alter(ck / "checkpoints" / "model.pt", how)
    over = over if "participants=3" in over else ["participants=2", *over]
    _refused(capsys, _evaluate(tmp_path / "run", "experiment=demo", *over, f"checkpoint={ck}"), needle)


def test_checkpoints_of_another_experiment_or_missing_are_refused(tmp_path, capsys, no_training, demo_run):
    _refused(capsys, _evaluate(tmp_path / "a", "experiment=exp1", "participants=2", f"checkpoint={demo_run}"),
             "trained for demo")
    _refused(capsys, _evaluate(tmp_path / "b", "experiment=demo", f"checkpoint={tmp_path / 'nowhere'}"), "not a directory")
    (tmp_path / "empty").mkdir()
    _refused(capsys, _evaluate(tmp_path / "c", "experiment=demo", f"checkpoint={tmp_path / 'empty'}"), "model.pt")


# --------------------------------------------------------------------------- run directories
def test_a_run_directory_of_another_run_is_refused_unless_overwrite(tmp_path, capsys, demo_run):
    run = _copy_run(demo_run, tmp_path / "run")
    _refused(capsys, _evaluate(run, "experiment=demo", "participants=2", "seed=1"), "holds another run", "seed")
    evaluate(make_cfg("experiment=demo", "participants=2", "seed=1", "overwrite=true"), out_dir=run)
    assert (run / "summary.json").is_file()


def test_same_settings_rewrite_with_one_line(tmp_path, capsys):
    evaluate(make_cfg("experiment=demo", "participants=2", "logger=none"), out_dir=tmp_path)
    capsys.readouterr()
    evaluate(make_cfg("experiment=demo", "participants=2", "logger=none"), out_dir=tmp_path)
    assert "same settings" in capsys.readouterr().err


def test_run_files_without_a_manifest_or_a_corrupt_one_are_refused(tmp_path, capsys, no_training):
    old = tmp_path / "old"
    old.mkdir()
    (old / "summary.json").write_text("{}")
    _refused(capsys, _evaluate(old, "experiment=demo"), "without a manifest")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "manifest.json").write_text("{not json")
    _refused(capsys, _evaluate(bad, "experiment=demo"), "manifest.json")


def test_a_file_where_the_run_directory_belongs_is_refused(tmp_path, capsys, no_training):
    (tmp_path / "f").write_text("x")
    _refused(capsys, _evaluate(tmp_path / "f" / "run", "experiment=demo"), "cannot create the run directory")


def test_a_full_disk_keeps_what_was_computed(tmp_path, capsys, monkeypatch):
    import pandas as pd

    real = pd.DataFrame.to_csv
    run_dir = tmp_path / "run"

    def full(self, path, *a, **k):
        if str(path).startswith(str(run_dir)):
            raise OSError(28, "No space left on device")
        return real(self, path, *a, **k)

    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    line = _refused(capsys, _evaluate(run_dir, "experiment=demo", "participants=2", "logger=none"),
                    "trials.csv", "No space left on device", "kept in")
    kept = Path(line.split("kept in ")[1])
    assert len(pd.read_csv(kept)) == 2 * 37
    assert not list(run_dir.glob("*.tmp"))
    assert (run_dir / "checkpoints" / "model.pt").is_file()  # what was finished before stays


# ------------------------------------------------------------------------------- the pool
@pytest.mark.parametrize("make,needle", [("missing", "no such run directory"), ("empty", "not a finished")])
def test_the_pool_refuses_what_is_not_a_run(tmp_path, capsys, make, needle):
    from neuroimagery.experiments import exp5_pool

    d = tmp_path / "r"
    if make == "empty":
        d.mkdir()
    _refused(capsys, lambda: cli.friendly_errors(exp5_pool.main)([str(d)]), needle)


# ------------------------------------------------------------------------ the command line
@pytest.mark.parametrize("args,needle", [(["experiment.stp_deg=1"], "stp_deg"), (["experiment.eta=nan"], "experiment.eta")])
def test_the_command_line_prints_one_error_line(tmp_path, args, needle):
    p = subprocess.run([sys.executable, str(ROOT / "train.py"), "experiment=demo", f"hydra.run.dir={tmp_path / 'r'}", *args],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 2, p.stderr
    assert [ln for ln in p.stderr.splitlines() if ln.strip()] == [ln for ln in p.stderr.splitlines() if ln.startswith("error:")]
    assert needle in p.stderr and "Traceback" not in p.stderr
