"""Experiment 1: exact Hebbian shortcuts, config checks, and a reduced end-to-end run."""
import json
import os

import pytest
import torch

from neuroimagery.models.params import SomParams
from conftest import make_cfg
from support_runs import reused_run

from neuroimagery.experiments.exp1.protocol import Exp1Config
from neuroimagery.nn.hebbian_closed_form import hebbian_indexed, hebbian_online, hebbian_shared
from neuroimagery.nn import AllToAll, Hebbian


def test_hebbian_shared_equals_online_rule():
    g = torch.Generator().manual_seed(0)
    w0 = torch.rand(3, 20, 16, generator=g) * 0.1
    pre = (torch.rand(30, 16, generator=g) > 0.6).float()
    post = torch.rand(30, 20, generator=g)
    assert torch.allclose(hebbian_shared(w0, pre, post, 0.3), hebbian_online(w0, pre, post, 0.3), atol=1e-6)


def test_hebbian_indexed_equals_online_rule():
    g = torch.Generator().manual_seed(1)
    P, T = 2, 25
    w0 = torch.rand(P, 12, 9, generator=g) * 0.1
    pre = torch.rand(P, T, 9, generator=g)
    idx = torch.randint(0, 4, (P, T), generator=g)
    ps = torch.rand(4, 12, generator=g)
    c = AllToAll(9, 12, participants=P, init="zeros", rules=Hebbian(0.3))
    c.weight.copy_(w0)
    for t in range(T):
        c.learn(pre[:, t:t + 1], ps[idx[:, t]].unsqueeze(1))
    assert torch.allclose(hebbian_indexed(w0, pre, idx, ps, 0.3), c.weight, atol=1e-6)


@pytest.mark.parametrize("key,value", [("hebb_eta", 0.0), ("max_cycles", 0), ("step_deg", 7.0)])
def test_config_rejects_bad_values(key, value):
    with pytest.raises(ValueError, match=key):
        Exp1Config(**{key: value})


def test_exp1_quick_run_writes_outputs_and_rotates(tmp_path):
    from neuroimagery.app.run import evaluate, train

    cfg = make_cfg("experiment=exp1", "participants=2", "preset=quick", "progress=false")
    s = evaluate(cfg, out_dir=tmp_path / "ev")
    for f in ("trials.csv", "summary.json", "report.md"):
        assert (tmp_path / "ev" / f).exists()
    assert list((tmp_path / "ev" / "figures").glob("*.png"))
    assert (tmp_path / "ev" / "tb").exists()
    js = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert set(js) >= {"experiment", "participants", "tests", "targets", "runtime_s"}
    rec = s["tests"]["recognition/none"]
    assert rec["n_trials"] == 2 * 52 and s["tests"]["generalisation/none"]["n_trials"] == 2 * 96
    assert rec["rt_r"] >= 0.9  # RT rises with |disparity|
    assert rec["rotation_success_rate"] >= 0.9
    # checkpoints load back and give the same answers
    train(cfg, out_dir=tmp_path / "tr")
    cfg2 = make_cfg("experiment=exp1", "participants=2", "preset=quick", "progress=false",
                    f"checkpoint={tmp_path / 'tr'}", "logger=none")
    s2 = evaluate(cfg2, out_dir=tmp_path / "ev2")
    assert s2["tests"]["recognition/none"]["rt_by_disparity"] == rec["rt_by_disparity"]


# ------------------------------------------------------------------ the full protocol (thesis 5.1.2)
@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """``EXP1_RUN=DIR`` reuses a finished ``evaluate.py experiment=exp1`` run made with the default
    settings (refused otherwise); without it one is made."""
    from neuroimagery.app.run import evaluate

    cfg = make_cfg("experiment=exp1", "progress=false", "logger=none")
    if os.environ.get("EXP1_RUN"):
        return reused_run("EXP1_RUN", cfg)
    return evaluate(cfg, out_dir=tmp_path_factory.mktemp("exp1_full"))


@pytest.mark.slow
def test_full_run_rotates_and_rt_rises_with_disparity(full_run):
    rec, gen = full_run["tests"]["recognition/none"], full_run["tests"]["generalisation/none"]
    assert full_run["participants"] == 10 and rec["n_trials"] == 10 * 52 and gen["n_trials"] == 10 * 96
    assert rec["rotation_success_rate"] >= 0.9 and gen["rotation_success_rate"] >= 0.9
    assert rec["rt_r"] >= 0.9


def test_summary_counts_the_participants_of_a_loaded_checkpoint(tmp_path):
    """checkpoint=DIR tests the loaded model's participants; another `participants` is refused by name."""
    from neuroimagery.core.errors import UserInputError
    from neuroimagery.app.run import evaluate, train

    def cfg(n, *more):
        return make_cfg("experiment=exp1", f"participants={n}", "preset=quick", "progress=false", "logger=none",
                        "experiment.som.iterations=50", *more)

    train(cfg(1), out_dir=tmp_path / "tr")
    with pytest.raises(UserInputError, match="participants 1 \\(stored\\) vs 3"):
        evaluate(cfg(3, f"checkpoint={tmp_path / 'tr'}"), out_dir=tmp_path / "ev")
    s = evaluate(cfg(1, f"checkpoint={tmp_path / 'tr'}"), out_dir=tmp_path / "ev")
    assert s["participants"] == 1 and s["tests"]["recognition/none"]["n_trials"] == 52


@pytest.mark.parametrize("centred_at", [1, 4, 10, None])
def test_rotation_makes_up_to_max_cycles_image_updates(centred_at):
    """Thesis 5.1.2: at most 10 rotation cycles (C1 then C2), each one image update; the rotation
    stops at the first cycle whose posture cluster is at the centre."""
    from neuroimagery.models.rotation_affordance import AffordanceRotationModel

    e = Exp1Config(som=SomParams(iterations=1))
    m = AffordanceRotationModel(e, 1, 0)
    calls = []

    def select_posture(pc=None, net=None):  # column 52 is 0 deg (the centre), column 0 is -90 deg
        calls.append(1)
        col = torch.full((pc if net is None else net).shape[:2], 52 if len(calls) == centred_at else 0, dtype=torch.long)
        return torch.zeros_like(col), col, torch.full_like(col, 7), None

    m.select_posture = select_posture
    out = m.trial(torch.zeros(1, 1, 1024), torch.zeros(1, 1, 1024))
    n = e.max_cycles if centred_at is None else centred_at - 1
    assert len(calls) == min(e.max_cycles, centred_at or e.max_cycles)
    assert int(out["steps"]) == n and bool(out["rotated_ok"]) == (centred_at is not None)
    assert int(out["rt"]) >= 7 * len(calls)


def test_answers_do_not_read_labels(tmp_path, monkeypatch):
    """The pairs' labels (objects, angles) shuffled after the protocol has chosen them, each trial's
    images kept: the model's answers, RTs and steps are unchanged."""
    import pandas as pd
    from support_labels import answers, shuffle_pair_labels

    from neuroimagery.config import validate
    from neuroimagery.experiments.exp1 import protocol as exp1
    from neuroimagery.app.run import RunDir
    from neuroimagery.vision.stimulus_sets import get_stimulus_set

    cfg = validate(make_cfg("experiment=exp1", "participants=2", "preset=quick", "progress=false", "logger=none",
                            "experiment.som.iterations=50"))
    model = exp1.train(cfg, RunDir(tmp_path, cfg))
    sset = get_stimulus_set("L")
    base = pd.DataFrame(exp1.run_test(cfg, model, sset, "generalisation")[0])
    true_pairs = exp1.test_pairs("generalisation", exp1.objects_of(sset))
    fake = shuffle_pair_labels(true_pairs, seed=3)
    images = exp1.edge_maps

    def true_images(cfg_, sset_, items):  # the images of the trials as chosen, whatever their labels say
        rot = [(p["rotated_object"], p["rotated_angle"]) for p in fake]
        tgt = [(p["target_object"], 0.0) for p in fake]
        real = ([(p["rotated_object"], p["rotated_angle"]) for p in true_pairs] if list(items) == rot else
                [(p["target_object"], 0.0) for p in true_pairs] if list(items) == tgt else None)
        assert real is not None, "unexpected image request"
        return images(cfg_, sset_, real)

    monkeypatch.setattr(exp1, "test_pairs", lambda test, objs: fake)
    monkeypatch.setattr(exp1, "edge_maps", true_images)
    shuffled = pd.DataFrame(exp1.run_test(cfg, model, sset, "generalisation")[0])
    assert (shuffled["rotated_angle"] != base["rotated_angle"]).any()
    pd.testing.assert_frame_equal(answers(shuffled), answers(base))
