"""Experiment 3: config checks, batched == solo, an end-to-end quick run."""
import json

import pytest
import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs, validate
from neuroimagery.experiments import exp3, protocol_ch6 as pc
from neuroimagery.nn import seeding
from neuroimagery.run import evaluate


def _cfg(*overrides, quick=True):
    register_configs()
    with initialize_config_dir(config_dir="/work/main/conf", version_base="1.3"):
        cfg = validate(compose("config", overrides=["experiment=exp3", *overrides]))
    cfg.preset = "quick" if quick else "full"
    return cfg


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="m1_sigma"):
        exp3.Exp3Config(m1_sigma=0.0)
    with pytest.raises(ValueError, match="match_threshold"):
        exp3.Exp3Config(match_threshold=2.0)


def test_batched_participants_equal_solo_runs():
    cfg = _cfg("participants=2", "logger=none", "experiment.quick_fm_images=300", "experiment.posture_iterations=100")
    both, solo = exp3.train_model(cfg, [0, 1]), exp3.train_model(cfg, [1])
    assert torch.allclose(both.c6.weight[1], solo.c6.weight[0], atol=1e-5)
    bank = pc.StimulusBank.build(pc.make_eye(cfg), pc.stimulus_set(cfg, "exp3-a", False), 32)
    table = pc.trial_table(bank, "recog", "none").iloc[:40]
    tgt = bank.maps[torch.as_tensor(table["target_row"].to_numpy().copy())]
    rot = bank.maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())]
    ob = both.run(tgt.expand(2, -1, -1), rot.expand(2, -1, -1), seeding.participant_generators(0, [0, 1], 100))
    os_ = solo.run(tgt.unsqueeze(0), rot.unsqueeze(0), seeding.participant_generators(0, [1], 100))
    for k in ("answer", "rt"):
        assert torch.equal(ob[k][1], os_[k][0]), k


def test_end_to_end_quick_run_writes_results(tmp_path):
    cfg = _cfg("participants=2", "logger.sample_trials=1", "experiment.quick_fm_images=1500")
    evaluate(cfg, out_dir=tmp_path)
    for f in ("trials.csv", "summary.json", "report.md", "checkpoints/exp3.pt", "figures/fig6_5a_rt.png"):
        assert (tmp_path / f).exists(), f
    s = json.loads((tmp_path / "summary.json").read_text())
    assert set(s["tests"]) == {"recog/none", "gen1/none", "gen2/none"}
    assert s["tests"]["recog/none"]["n_trials"] == 2 * 64


@pytest.mark.slow
def test_full_protocol(tmp_path):
    s = evaluate(_cfg("logger=none", quick=False), out_dir=tmp_path)
    assert s["tests"]["recog/none"]["n_trials"] == 1920
