"""Experiment 2: config checks, babbling, SOM equivalence, the SS competition, quick and full runs."""
import os
from dataclasses import replace

import cv2
import numpy as np
import pytest
import torch
from conftest import make_cfg
from support_runs import reused_run

from neuroimagery.experiments.exp2 import Exp2Config
from neuroimagery.nn.som import fit_windowed as som_fit_windowed
from neuroimagery.models.rotation_motor import ANGLES, MotorRotationModel
from neuroimagery.nn import SOM, participant_generators

def _cfg(*overrides):
    return make_cfg("experiment=exp2", "progress=false", *overrides)


@pytest.mark.parametrize("key,value", [("proprio_gain", 1.5), ("som_iterations", 0), ("som_method", "x"),
                                       ("som_cutoff", 1.0), ("som_threads", 0)])
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
    # the recorded next posture is the current one moved one 30-deg step by the action
    assert torch.equal(b["nxt"], b["cur"] + b["act"])


def test_m11_som_methods_agree_on_a_shortened_schedule():
    """M1_1 on its 98 (object, current, desired) patterns, 2 participants, 10 steps of the
    configured schedule compressed: windowed, factored and online give the same winners, the
    same quantisation and topographic errors, and the same weights up to float rounding."""
    e = Exp2Config(som_iterations=10)
    m = MotorRotationModel(e, 2, 0)
    ang = torch.tensor(ANGLES)
    o, c, d = (t.reshape(-1) for t in torch.meshgrid(torch.arange(2), torch.arange(7), torch.arange(7), indexing="ij"))
    X = torch.cat([m.ss_code(o, ang[c]), m.pmc1_code(ang[d])], -1)
    order = m.babble(10)
    order = order["obj"] * 49 + order["cur"] * 7 + order["des"]
    res = {}
    for method in ("online", "factored", "windowed"):
        som = SOM((64, 64), 6200, generators=participant_generators(0, 2, stream=6), init=(0.0, e.init_high),
                  eta=e.som_eta, eta_final=e.som_eta_final, sigma=e.som_sigma, sigma_final=e.som_sigma_final,
                  iterations=10)
        som.rule.cutoff = e.som_cutoff
        som.train()
        win = som_fit_windowed(som, X, order) if method == "windowed" else som.fit(X, order=order, method=method)
        res[method] = (win, som.weight.clone(), som.quantization_error(X), som.topographic_error(X))
    ref = res["online"]
    for method in ("factored", "windowed"):
        win, w, qe, te = res[method]
        assert torch.equal(win, ref[0]), method
        assert (w - ref[1]).abs().max() < 1e-5, method
        assert torch.allclose(qe, ref[2], atol=1e-4) and torch.equal(te, ref[3]), method


def test_proprioception_preshapes_the_ss_competition():
    """The weaker felt posture alone is far slower to win SS than the forward model's cluster; on
    the predicted cluster it speeds the competition, elsewhere it slows it without taking the win."""
    e = Exp2Config()
    m = MotorRotationModel(e, 1, 0)
    obj = torch.tensor([0])

    def prof(angle, gain=1.0):
        return gain * m.ss_code(obj, torch.tensor([angle])).reshape(1, 31, 100).amax(-2)

    def run(felt):
        s, u0 = prof(0.0), None
        if felt is not None:
            p = prof(felt, e.proprio_gain)
            s, u0 = s + p, e.field_h + e.field_gain * p
        return m.ss_field(e.field_gain * s, max_cycles=e.field_max_cycles, u0=u0)

    alone = m.ss_field(e.field_gain * prof(60.0, e.proprio_gain), max_cycles=e.field_max_cycles)
    none, match, mis = run(None), run(0.0), run(60.0)
    assert int(alone.cycles) > 2 * int(none.cycles)
    assert int(match.cycles) < int(none.cycles) < int(mis.cycles)
    assert int(mis.winner) == int(none.winner) == int(match.winner)


def _draw_l(path, mirror):
    img = np.full((120, 120, 3), 255, np.uint8)
    cv2.rectangle(img, (40, 20), (60, 100), (0, 0, 0), -1)
    cv2.rectangle(img, (40, 20), (90, 40), (0, 0, 0), -1)
    cv2.imwrite(str(path), img[:, ::-1] if mirror else img)


@pytest.mark.slow
def test_exp2_quick_run_with_a_user_folder_adds_custom_results(tmp_path):
    from neuroimagery.run import evaluate

    folder = tmp_path / "shapes"
    folder.mkdir()
    _draw_l(folder / "a.png", False)
    _draw_l(folder / "b.png", True)
    cfg = _cfg("participants=1", "preset=quick", "logger=none", "stimuli=folder", f"stimuli.path={folder}")
    s = evaluate(cfg, out_dir=tmp_path / "run")
    for f in ("trials.csv", "summary.json", "report.md"):
        assert (tmp_path / "run" / f).exists()
    assert set(s["tests"]) >= {"all/none", "all/match", "all/mismatch", "custom/none"}
    assert s["tests"]["custom/none"]["n_trials"] == 196
    assert "User stimuli" in (tmp_path / "run" / "report.md").read_text()


# ------------------------------------------------------------------ the full protocol (thesis 5.2.2)
@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """``EXP2_RUN=DIR`` reuses a finished ``evaluate.py experiment=exp2`` run made with the default
    settings (refused otherwise); without it one is made."""
    cfg = _cfg("logger=none")
    if os.environ.get("EXP2_RUN"):
        return reused_run("EXP2_RUN", cfg)
    from neuroimagery.run import evaluate

    return evaluate(cfg, out_dir=tmp_path_factory.mktemp("exp2_full"))


@pytest.mark.slow
def test_full_run_rotates_and_answers(full_run):
    n = full_run["tests"]["all/none"]
    assert full_run["participants"] == 10 and n["n_trials"] == 10 * 196
    assert n["rotation_success_rate"] >= 0.90
    assert n["correct_rate"] >= 0.75
    assert n["rt_r"] >= 0.9


@pytest.mark.slow
def test_full_run_mismatch_slows_without_costing_accuracy(full_run):
    pr = full_run["proprioception"]
    m = pr["rt_mismatch_vs_none_paired"]
    assert m["mean_a"] > m["mean_b"] and m["p"] < 0.05
    assert pr["rt_match_vs_none_paired"]["mean_a"] < m["mean_b"]
    acc = pr["correct_mismatch_vs_none"]
    assert abs(acc["rate_a"] - acc["rate_b"]) <= 0.03


@pytest.mark.slow
def test_full_run_object_type_has_no_effect(full_run):
    assert full_run["object_type_anova"]["p"] > 0.05


def test_row_cache_and_distinct_rows_equal_the_direct_products():
    """Products looked up by key (computed once per distinct key, over at least MIN_ROWS rows)
    are bit-identical to the product over the whole batch, also when a call brings one new key."""
    from neuroimagery.models.rotation_motor import RowCache, distinct_rows

    g = torch.Generator().manual_seed(0)
    P, n_keys, n_in, n_out = 3, 40, 4096, 300  # the sizes of C9 (with one row, MKL rounds differently)
    codes = torch.rand(n_keys, n_in, generator=g) * (torch.rand(n_keys, n_in, generator=g) < 0.1)
    W = torch.rand(P, n_out, n_in, generator=g)
    fn = lambda k: (torch.bmm(codes[k], W.transpose(1, 2)),)  # noqa: E731
    cache = RowCache(P, n_keys, fn)
    for keys in (torch.randint(20, (P, 50), generator=g), torch.randint(n_keys, (P, 60), generator=g),
                 torch.full((P, 30), 3).index_fill_(1, torch.tensor([7]), 39)):  # the last brings one new key
        (got,) = cache(keys)
        assert torch.equal(got, fn(keys)[0])
    x = codes[torch.randint(5, (P, 64), generator=g)]
    net = lambda v: torch.bmm(v, W.transpose(1, 2))  # noqa: E731
    assert torch.equal(distinct_rows(net, x), net(x))


def test_trial_lookups_equal_direct_computation():
    """The trial's tables (SS codes, C9 / C10 by M1_1 winner, C2 by SS code) equal the products
    computed on a whole batch, as the trial did before it looked them up."""
    m = MotorRotationModel(Exp2Config(), 2, 0)  # the initial (random) weights serve as well as trained ones
    m.eval()
    g = torch.Generator().manual_seed(1)
    ss_set, table, motor, image = m._lookups()
    ang = torch.tensor(ANGLES)
    col_angle = m.ss.coords[:100, 1]
    ss_i = torch.randint(214, (2, 196), generator=g)
    obj = torch.where(ss_i < 14, ss_i // 7, (ss_i - 14) // 100)
    angle = torch.where(ss_i < 14, ang[ss_i % 7], col_angle[(ss_i - 14) % 100])
    assert torch.equal(ss_set[ss_i], m.ss_code(obj, angle))
    des_i = torch.randint(7, (2, 196), generator=g)
    bmu = table(ss_i, des_i)
    assert torch.equal(bmu, m.m11.bmu(torch.cat([m.ss_code(obj, angle), m.pmc1_code(ang[des_i])], -1)))
    mb = m.som_bump(m.m11, bmu=bmu)
    a9, a10 = motor(bmu)
    assert torch.equal(a9, m.c9.net(mb)) and torch.equal(a10, m.c10.net(mb))
    assert torch.equal(image(ss_i)[0], m.c2.net(m.ss_code(obj, angle)))
    assert m._lookups()[2] is motor  # built once per set of weights
    m.c9.weight.add_(0.0)
    assert m._lookups()[2] is not motor  # rebuilt after the weights change


def test_compact_checkpoint_round_trip_is_bit_exact(tmp_path):
    """The checkpoint written by training holds the trainer's factors, not the weights; loading
    forms every weight again by the trainer's own products: every state tensor comes back bit for
    bit. An unknown format, or factors that do not rebuild the saved weights (other settings),
    fail with the file named. A full state_dict checkpoint still loads."""
    from types import SimpleNamespace

    from neuroimagery.errors import UserInputError
    from neuroimagery.experiments.protocol_ch5 import load_model

    e = Exp2Config(som_iterations=30, hebb_steps=60, c5_epochs=1)
    g = torch.Generator().manual_seed(3)
    images = {(o, a): (torch.rand(1024, generator=g) > 0.8).float() for o in (0, 1) for a in ANGLES}
    m = MotorRotationModel(e, 2, 0)
    m.fit(images)
    ref = m.state_dict()
    path = tmp_path / "checkpoints" / "model.pt"
    path.parent.mkdir()
    torch.save(m.compact_state(), path)
    assert path.stat().st_size < sum(v.numel() * v.element_size() for v in ref.values()) / 5
    loaded = load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e).state_dict()
    assert loaded.keys() == ref.keys()
    for k, v in ref.items():
        assert loaded[k].dtype == v.dtype and torch.equal(loaded[k], v), k
    # other settings draw other initial weights: the rebuilt weights would differ, and loading says so
    with pytest.raises(UserInputError, match="model.pt.*differ"):
        load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, replace(e, init_high=0.2))
    with pytest.raises(ValueError, match="unknown checkpoint format 'x'"):
        MotorRotationModel(e, 2, 0).load_compact_state({**m.compact_state(), "format": "x"})
    torch.save({"format": "neuroimagery.exp2.factors/999", "participants": 2}, path)
    with pytest.raises(UserInputError, match=r"model\.pt: unknown format 'neuroimagery\.exp2\.factors/999'"):
        load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e)
    torch.save({"state_dict": ref, "participants": 2}, path)  # the full form of earlier checkpoints
    loaded = load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e).state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in ref.items())


def test_summary_counts_the_participants_of_a_loaded_checkpoint(tmp_path):
    """checkpoint=DIR tests the loaded model's participants; another `participants` is refused by name."""
    from neuroimagery import manifest as mf
    from neuroimagery.config import validate
    from neuroimagery.errors import UserInputError
    from neuroimagery.experiments import exp2
    from neuroimagery.run import RunDir, evaluate

    small = ("experiment.som_iterations=30", "experiment.hebb_steps=60", "experiment.c5_epochs=1", "logger=none")
    e = Exp2Config(som_iterations=30, hebb_steps=60, c5_epochs=1)
    g = torch.Generator().manual_seed(3)
    m = MotorRotationModel(e, 1, 0)
    m.fit({(o, a): (torch.rand(1024, generator=g) > 0.8).float() for o in (0, 1) for a in ANGLES})
    conf = validate(_cfg("participants=1", *small))
    RunDir(tmp_path / "tr", conf, manifest=mf.build(conf, exp2)).save_checkpoint("model", m.compact_state())
    with pytest.raises(UserInputError, match="participants 1 \\(stored\\) vs 3"):
        evaluate(_cfg("participants=3", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    s = evaluate(_cfg("participants=1", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    assert s["participants"] == 1 and s["tests"]["all/none"]["n_trials"] == 196
