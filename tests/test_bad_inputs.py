"""Malformed checkpoints, run directories and pool inputs: each is refused with one ``error:`` line
naming the culprit, exit status 2, no traceback, within seconds and before any training starts.

The cases run in-process through the same wrappers the command line uses (``friendly_errors``), so
the table costs the suite little time. The other tables of bad inputs: ``test_bad_inputs_sizes.py``
(memory, threads, declared bounds), ``test_bad_inputs_settings.py`` (settings and key names),
``test_bad_inputs_stimuli.py`` (stimulus folders and images), ``test_bad_inputs_babble.py``.
"""
from __future__ import annotations

import pickle
from pathlib import Path

import pytest
import torch

from neuroimagery.app import cli
from neuroimagery.app.run import evaluate, train

from conftest import make_cfg
from support_bad_inputs import evaluating, no_training, refused  # noqa: F401 (fixture)


class _Marker:
    """A pickle that would create a file if it were ever unpickled unsafely."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


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
    refused(capsys, evaluating(tmp_path / "run", "experiment=demo", "participants=2", f"checkpoint={ck}"),
             "model.pt", "nothing in it was run")
    assert not marker.exists()
    torch.save({"state_dict": _Marker(marker)}, ck / "checkpoints" / "model.pt")  # the zip format too
    refused(capsys, evaluating(tmp_path / "run", "experiment=demo", "participants=2", f"checkpoint={ck}"), "model.pt")
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
    refused(capsys, evaluating(tmp_path / "run", "experiment=demo", *over, f"checkpoint={ck}"), needle)


def test_checkpoints_of_another_experiment_or_missing_are_refused(tmp_path, capsys, no_training, demo_run):
    refused(capsys, evaluating(tmp_path / "a", "experiment=exp1", "participants=2", f"checkpoint={demo_run}"),
             "trained for demo")
    refused(capsys, evaluating(tmp_path / "b", "experiment=demo", f"checkpoint={tmp_path / 'nowhere'}"), "not a directory")
    (tmp_path / "empty").mkdir()
    refused(capsys, evaluating(tmp_path / "c", "experiment=demo", f"checkpoint={tmp_path / 'empty'}"), "model.pt")


# --------------------------------------------------------------------------- run directories
def test_a_run_directory_of_another_run_is_refused_unless_overwrite(tmp_path, capsys, demo_run):
    run = _copy_run(demo_run, tmp_path / "run")
    refused(capsys, evaluating(run, "experiment=demo", "participants=2", "seed=1"), "holds another run", "seed")
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
    refused(capsys, evaluating(old, "experiment=demo"), "without a manifest")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "manifest.json").write_text("{not json")
    refused(capsys, evaluating(bad, "experiment=demo"), "manifest.json")


def test_a_file_where_the_run_directory_belongs_is_refused(tmp_path, capsys, no_training):
    (tmp_path / "f").write_text("x")
    refused(capsys, evaluating(tmp_path / "f" / "run", "experiment=demo"), "cannot create the run directory")


def test_a_full_disk_keeps_what_was_computed(tmp_path, capsys, monkeypatch):
    import pandas as pd

    real = pd.DataFrame.to_csv
    run_dir = tmp_path / "run"

    def full(self, path, *a, **k):
        if str(path).startswith(str(run_dir)):
            raise OSError(28, "No space left on device")
        return real(self, path, *a, **k)

    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    line = refused(capsys, evaluating(run_dir, "experiment=demo", "participants=2", "logger=none"),
                    "trials.csv", "No space left on device", "kept in")
    kept = Path(line.split("kept in ")[1])
    assert len(pd.read_csv(kept)) == 2 * 37
    assert not list(run_dir.glob("*.tmp"))
    assert (run_dir / "checkpoints" / "model.pt").is_file()  # what was finished before stays


# ------------------------------------------------------------------------------- the pool
@pytest.mark.parametrize("make,needle", [("missing", "no such run directory"), ("empty", "not a finished")])
def test_the_pool_refuses_what_is_not_a_run(tmp_path, capsys, make, needle):
    from neuroimagery.app import pool

    d = tmp_path / "r"
    if make == "empty":
        d.mkdir()
    refused(capsys, lambda: cli.friendly_errors(pool.main)([str(d)]), needle)
