"""Experiment 4's compact checkpoint: the forward models' training sequence instead of their
weights; a model loaded from it is the trained model, tensor for tensor, and tests the same."""
import filecmp

import pytest
import torch
from conftest import make_cfg
from support_runs import rehash

from neuroimagery.config import validate
from neuroimagery.core.errors import UserInputError
from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.core.manifest import tensor_hash
from neuroimagery.models import sequence_checkpoint as sc
from neuroimagery.app.run import evaluate

SMALL = ("experiment=exp4", "preset=quick", "participants=2", "logger=none", "progress=false",
         "experiment.quick.fm_images=200", "experiment.posture.iterations=50", "experiment.noise_tests=[]",
         "experiment.selection.max_steps=3", "experiment.percept.looks=2")
# (2 looks per test item instead of 16: what a checkpoint holds and how its run tests do not depend
# on how many looks the tests build, and building them is a third of a run's time)


@pytest.fixture(scope="module")
def trained():
    """The two participants of ``SMALL``, trained once for the tests that only read the model."""
    cfg = validate(make_cfg(*SMALL))
    return cfg, exp4.train_model(cfg, [0, 1])


def test_active_units_round_trip():
    g = torch.Generator().manual_seed(0)
    X = (torch.rand(2, 5, 40, generator=g) < 0.2).float()
    X[0, 1] = 0  # an empty image
    idx = sc.active_units(X)
    assert idx.dtype == torch.int16 and idx.shape[-1] == int(X.sum(-1).max())
    assert torch.equal(sc.from_active(idx, 40), X)
    assert (idx[0, 1] == -1).all()
    with pytest.raises(ValueError, match="0/1"):
        sc.active_units(X * 0.5)


def test_a_compact_checkpoint_rebuilds_the_trained_model(trained):
    cfg, model = trained
    ck = sc.compact_state(model)
    assert ck["format"] == sc.FORMAT and not set(sc.KEYS) & set(ck["state"])
    full = sum(v.numel() * v.element_size() for v in model.state_dict().values())
    kept = sum(v.numel() * v.element_size() for part in (ck["state"], ck["fm_training"], ck["probe"])
               for v in part.values() if isinstance(v, torch.Tensor))
    assert kept < full / 20
    fresh = exp4._model(cfg, ck["participants"])
    sc.load_compact_state(fresh, ck)
    assert not fresh.training
    for k, v in model.state_dict().items():
        assert torch.equal(fresh.state_dict()[k], v), k
    # a checkpoint whose stored rows do not match what the sequence forms is refused
    bad = {**ck, "probe": {**ck["probe"], "fm.1.weight": ck["probe"]["fm.1.weight"] + 1e-3}}
    with pytest.raises(ValueError, match=r"fm\.1\.weight"):
        sc.load_compact_state(exp4._model(cfg, ck["participants"]), bad)
    with pytest.raises(ValueError, match="needs a model trained"):
        sc.compact_state(exp4._model(cfg, [0, 1]))


def test_checkpoint_from_compact_tests_as_the_training_run(tmp_path, monkeypatch):
    """The three runs compare their trials.csv: they draw no figures (nearly half a run's time)."""
    monkeypatch.setattr(exp4, "_figures", lambda *a, **k: None)
    s = evaluate(make_cfg(*SMALL), out_dir=tmp_path / "run")
    state = torch.load(tmp_path / "run" / "checkpoints" / "exp4.pt", weights_only=True)
    assert state["format"] == sc.FORMAT and "state_dict" not in state
    evaluate(make_cfg(*SMALL, f"checkpoint={tmp_path / 'run'}"), out_dir=tmp_path / "again")
    assert filecmp.cmp(tmp_path / "run" / "trials.csv", tmp_path / "again" / "trials.csv", shallow=False)
    assert s["tests"]
    # a full checkpoint (state_dict, as earlier versions wrote) still loads, and tests the same
    model = exp4.load(validate(make_cfg(*SMALL)), tmp_path / "run")
    full = {"state_dict": model.state_dict(), "participants": model.participant_ids}
    torch.save({**full, "manifest": {**state["manifest"], "tensor_hash": tensor_hash(full)}},
               tmp_path / "run" / "checkpoints" / "exp4.pt")
    rehash(tmp_path / "run")  # as the run that wrote it would have recorded it in manifest.json
    evaluate(make_cfg(*SMALL, f"checkpoint={tmp_path / 'run'}"), out_dir=tmp_path / "from_full")
    assert filecmp.cmp(tmp_path / "run" / "trials.csv", tmp_path / "from_full" / "trials.csv", shallow=False)


def test_a_compact_checkpoint_of_other_participants_is_refused_with_its_path(tmp_path, trained):
    cfg, model = trained
    ck = sc.compact_state(model)
    (tmp_path / "checkpoints").mkdir()
    torch.save({**ck, "participants": [0, 1, 2]}, tmp_path / "checkpoints" / "exp4.pt")
    with pytest.raises(UserInputError, match=r"checkpoints/exp4.pt: its training sequence is of 2 participants .* the model of 3 participants"):
        exp4.load(cfg, tmp_path)
