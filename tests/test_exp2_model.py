"""Experiment 2: config checks, babbling, and a reduced end-to-end run."""
import pytest
import torch

from neuroimagery.experiments.exp2 import Exp2Config
from neuroimagery.models.rotation_motor import MotorRotationModel


@pytest.mark.parametrize("key,value", [("proprio_gain", 1.5), ("som_iterations", 0), ("som_method", "x")])
def test_config_rejects_bad_values(key, value):
    with pytest.raises(ValueError, match=key):
        Exp2Config(**{key: value})


def test_babbling_moves_toward_the_desired_posture():
    m = MotorRotationModel(Exp2Config(som_iterations=10), 2, 0)
    b = m.babble(200)
    assert b["cur"].shape == (2, 200)
    assert ((b["nxt"] >= 0) & (b["nxt"] <= 6)).all()
    # the action always points from the current to the desired posture, and N2 only when there
    assert torch.equal(b["act"], torch.sign(b["des"] - b["cur"]))


@pytest.mark.slow
def test_exp2_quick_run_writes_outputs(tmp_path):
    from hydra import compose, initialize_config_dir

    from neuroimagery.config import register_configs
    from neuroimagery.run import evaluate

    register_configs()
    with initialize_config_dir(config_dir="/work/main/conf", version_base="1.3"):
        cfg = compose("config", overrides=["experiment=exp2", "participants=1", "preset=quick", "progress=false"])
    s = evaluate(cfg, out_dir=tmp_path)
    for f in ("trials.csv", "summary.json", "report.md"):
        assert (tmp_path / f).exists()
    assert set(s["tests"]) >= {"all/none", "all/match", "all/mismatch"}
    assert s["tests"]["all/none"]["n_trials"] == 196
