"""Stored runs are judged by one function (``manifest.usable_run``) for ``pool``, ``checkpoint=``
and ``experiment.engine.reuse_libraries``: a manifest that lacks a key this package writes is
refused alike by all three, and a file whose hash in ``manifest.json`` does not match the file
(the file replaced, or the hash edited by hand) is refused, not only a checkpoint whose inner hash
is wrong."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch

from neuroimagery.app import cli, pool

from neuroimagery.core import manifest as mf

from conftest import make_cfg
from support_bad_inputs import evaluating, no_training, refused  # noqa: F401 (fixture)


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    from neuroimagery.app.run import evaluate

    d = tmp_path_factory.mktemp("stored") / "run"
    evaluate(make_cfg("experiment=demo", "participants=2", "logger=none"), out_dir=d)
    return d


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _edit_manifest(d: Path, change) -> None:
    m = json.loads((d / "manifest.json").read_text())
    change(m)
    (d / "manifest.json").write_text(json.dumps(m))


def _use(how: str, d: Path, tmp_path: Path):
    if how == "checkpoint":
        return evaluating(tmp_path / "new", "experiment=demo", "participants=2", "logger=none", f"checkpoint={d}")
    if how == "pool":
        return lambda: cli.friendly_errors(pool.main)([str(d)])
    return evaluating(tmp_path / "new", "experiment=exp5", f"experiment.engine.reuse_libraries={d}")


@pytest.mark.parametrize("use", ["checkpoint", "pool", "reuse_libraries"])
def test_a_manifest_without_its_seed_is_refused_by_every_use(demo_run, tmp_path, capsys, no_training, use):
    d = _copy(demo_run, tmp_path / "run")
    _edit_manifest(d, lambda m: m.pop("seed"))
    if use == "reuse_libraries":
        _edit_manifest(d, lambda m: m.update(experiment="exp5"))
    refused(capsys, _use(use, d, tmp_path), f"{d / 'manifest.json'}: no 'seed'")
    assert not (tmp_path / "new").exists()


def test_a_checkpoint_hash_edited_in_the_manifest_is_refused(demo_run, tmp_path, capsys, no_training):
    d = _copy(demo_run, tmp_path / "run")
    _edit_manifest(d, lambda m: m["files"].update({"checkpoints/model.pt": "0" * 64}))
    refused(capsys, _use("checkpoint", d, tmp_path), f"{d / 'checkpoints' / 'model.pt'}: changed since the run finished")


def test_a_checkpoint_replaced_with_a_consistent_file_is_refused(demo_run, tmp_path, capsys, no_training):
    """The file's own hash agrees with its tensors, but not with the hash the run recorded."""
    d = _copy(demo_run, tmp_path / "run")
    ck = d / "checkpoints" / "model.pt"
    state = torch.load(ck, weights_only=True)
    man = state.pop("manifest")
    state["state_dict"] = {k: v * 1.01 if v.is_floating_point() else v for k, v in state["state_dict"].items()}
    torch.save({**state, "manifest": {**man, "tensor_hash": mf.tensor_hash(state)}}, ck)
    refused(capsys, _use("checkpoint", d, tmp_path), f"{ck}: changed since the run finished")


def test_a_pooled_file_whose_hash_was_edited_is_refused(demo_run, tmp_path, capsys):
    d = _copy(demo_run, tmp_path / "run")
    _edit_manifest(d, lambda m: m["files"].update({"summary.json": "0" * 64}))
    refused(capsys, _use("pool", d, tmp_path), f"{d / 'summary.json'}: changed since the run finished")


def test_an_unreadable_manifest_of_reuse_libraries_is_refused(tmp_path, capsys, no_training):
    d = tmp_path / "other"
    (d / "checkpoints").mkdir(parents=True)
    (d / "manifest.json").write_text("{cut")
    refused(capsys, _use("reuse_libraries", d, tmp_path), "experiment.engine.reuse_libraries", "cannot be read")


def test_libraries_of_an_exp5_run_that_stopped_may_be_reused(tmp_path):
    """Each library is checked when it is read (its seed and settings), so a run killed midway is usable."""
    from neuroimagery.experiments.exp5.checks import check_reuse

    d = tmp_path / "killed"
    (d / "checkpoints").mkdir(parents=True)
    (d / "manifest.json").write_text(json.dumps({"experiment": "exp5", "seed": 0, "participants": 1, "settings": {},
                                                 "state": "running", "trained": False}))
    check_reuse(str(d))
    manifest = mf.usable_run(d, "reuse", experiment="exp5", need="any", files=None)
    assert manifest["seed"] == 0
