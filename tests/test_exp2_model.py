"""Experiment 2: config checks, babbling, SOM equivalence, the SS competition, quick and full runs."""
import os
import re
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from neuroimagery.models.params import SomParams
from conftest import make_cfg
from support_numerics import assert_same_threshold, assert_same_winner, assert_within
from support_runs import reused_run

from neuroimagery.experiments.exp2.protocol import Exp2Config
from neuroimagery.nn.som_windowed import fit_windowed as som_fit_windowed
from neuroimagery.nn.functional import squared_norms
from neuroimagery.models.rotation_motor import ANGLES, MotorRotationModel
from neuroimagery.nn import SOM, participant_generators
from neuroimagery.nn.numerics import cast_bound, rounding_bound_nonneg

def _cfg(*overrides):
    return make_cfg("experiment=exp2", "progress=false", *overrides)


@pytest.mark.parametrize("key,value", [("proprio_gain", 1.5), ("som.iterations", 0), ("som.method", "x"),
                                       ("som.cutoff", 1.0), ("som.threads", 0)])
def test_config_rejects_bad_values(key, value):
    with pytest.raises(ValueError, match=key):
        if key.startswith("som."):
            Exp2Config(som=SomParams(**{key[4:]: value}))
        else:
            Exp2Config(**{key: value})


def test_babbling_moves_toward_the_desired_posture():
    m = MotorRotationModel(Exp2Config(som=SomParams(iterations=10, cutoff=0.01, cluster_sigma=1.0)), 2, 0)
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
    e = Exp2Config(som=SomParams(iterations=10, cutoff=0.01, cluster_sigma=1.0))
    m = MotorRotationModel(e, 2, 0)
    ang = torch.tensor(ANGLES)
    o, c, d = (t.reshape(-1) for t in torch.meshgrid(torch.arange(2), torch.arange(7), torch.arange(7), indexing="ij"))
    X = torch.cat([m.ss_code(o, ang[c]), m.pmc1_code(ang[d])], -1)
    order = m.babble(10)
    order = order["obj"] * 49 + order["cur"] * 7 + order["des"]
    res = {}
    for method in ("online", "factored", "windowed"):
        som = SOM((64, 64), 6200, generators=participant_generators(0, 2, stream=6), init=(0.0, e.init_high),
                  eta=e.som.eta, eta_final=e.som.eta_final, sigma=e.som.sigma, sigma_final=e.som.sigma_final,
                  iterations=10)
        som.rule.cutoff = e.som.cutoff
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
            s, u0 = s + p, e.field.h + e.field.gain * p
        return m.ss_field(e.field.gain * s, max_cycles=e.field.max_cycles, u0=u0)

    alone = m.ss_field(e.field.gain * prof(60.0, e.proprio_gain), max_cycles=e.field.max_cycles)
    none, match, mis = run(None), run(0.0), run(60.0)
    assert int(alone.cycles) > 2 * int(none.cycles)
    assert int(match.cycles) < int(none.cycles) < int(mis.cycles)
    # 0 deg lies midway between two columns (-0.9 and +0.9 deg) whose inputs are equal: rounding in
    # the field decides which of them wins (it can differ between CPUs); either is the prediction's
    col_angle = m.ss.coords[:100, 1]
    p0 = prof(0.0)[0]
    assert float(col_angle[50]) == -float(col_angle[49]) < 1.0
    assert (p0[49] - p0[50]).abs() <= 2 * cast_bound(p0[49])  # equal up to exp's rounding (2 ulp)
    assert all(int(d.winner) in (49, 50) for d in (none, match, mis))


def _draw_l(path, mirror):
    img = np.full((120, 120, 3), 255, np.uint8)
    cv2.rectangle(img, (40, 20), (60, 100), (0, 0, 0), -1)
    cv2.rectangle(img, (40, 20), (90, 40), (0, 0, 0), -1)
    cv2.imwrite(str(path), img[:, ::-1] if mirror else img)


@pytest.mark.slow
def test_exp2_quick_run_with_a_user_folder_adds_custom_results(tmp_path):
    from neuroimagery.app.run import evaluate

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
    from neuroimagery.app.run import evaluate

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


def test_row_cache_and_distinct_rows_agree_with_the_direct_products():
    """Products looked up by key (computed once per distinct key, over at least MIN_ROWS rows)
    agree with the product over the whole batch, also when a call brings one new key. The two
    products have other shapes, which BLAS may block and sum in another order (with oneMKL on
    AVX-512, 8-row and larger products round differently), so they agree within the rounding
    bound of their 4096-term sums, with the same strongest output on every row."""
    from neuroimagery.nn.row_cache import RowCache, distinct_rows

    g = torch.Generator().manual_seed(0)
    P, n_keys, n_in, n_out = 3, 40, 4096, 300  # the sizes of C9
    codes = torch.rand(n_keys, n_in, generator=g) * (torch.rand(n_keys, n_in, generator=g) < 0.1)
    W = torch.rand(P, n_out, n_in, generator=g)
    fn = lambda k: (torch.bmm(codes[k], W.transpose(1, 2)),)  # noqa: E731
    bound = lambda ref: rounding_bound_nonneg(ref, n_in)  # noqa: E731  (every term is >= 0)
    cache = RowCache(P, n_keys, fn)
    for keys in (torch.randint(20, (P, 50), generator=g), torch.randint(n_keys, (P, 60), generator=g),
                 torch.full((P, 30), 3).index_fill_(1, torch.tensor([7]), 39)):  # the last brings one new key
        (got,) = cache(keys)
        ref = fn(keys)[0]
        assert_within(got, ref, bound(ref), "RowCache")
        assert_same_winner(got.argmax(-1), ref, bound(ref), what="RowCache")
    wrong = RowCache(P, n_keys, lambda k: fn((k + 1) % n_keys))(keys)[0]  # the rows of other keys are caught
    with pytest.raises(AssertionError, match="rounding bound"):
        assert_within(wrong, ref, bound(ref), "other keys")
    x = codes[torch.randint(5, (P, 64), generator=g)]
    net = lambda v: torch.bmm(v, W.transpose(1, 2))  # noqa: E731
    got, ref = distinct_rows(net, x), net(x)
    assert_within(got, ref, bound(ref), "distinct_rows")
    assert_same_winner(got.argmax(-1), ref, bound(ref), what="distinct_rows")


def test_trial_lookups_agree_with_direct_computation():
    """The trial's tables (SS codes, M1_1 winners, C9 / C10 by M1_1 winner, C2 by SS code) agree
    with the products computed on a whole batch, as the trial did before it looked them up: within
    the rounding bound of each product (their shapes differ), with the same M1_1 winners, M1_2
    actions, C10 peaks and C2 image units on, wherever that bound decides them."""
    m = MotorRotationModel(Exp2Config(), 2, 0)  # the initial (random) weights serve as well as trained ones
    m.eval()
    g = torch.Generator().manual_seed(1)
    ss_set, table, motor, image = m._lookups()
    ang = torch.tensor(ANGLES)
    col_angle = m.ss.coords[:100, 1]
    ss_i = torch.randint(214, (2, 196), generator=g)
    obj = torch.where(ss_i < 14, ss_i // 7, (ss_i - 14) // 100)
    angle = torch.where(ss_i < 14, ang[ss_i % 7], col_angle[(ss_i - 14) % 100])
    code = m.ss_code(obj, angle)
    # Gaussian tuning curves: the same arithmetic element by element but exp, which every
    # implementation (vectorised or not) gives within 1 ulp: 2 ulp apart, +1 for the amplitude
    assert_within(ss_set[ss_i], code, cast_bound(code) * 3, "SS codes")
    des_i = torch.randint(7, (2, 196), generator=g)
    bmu = table(ss_i, des_i)
    x = torch.cat([ss_set[ss_i], m.pmc1_code(ang)[des_i]], -1)  # the codes the table was built from
    w = m.m11.weight
    # |w|^2 - 2 w.x + |x|^2: at most 6200 terms in each sum, two more roundings to combine them
    mag = squared_norms(w).unsqueeze(1) + 2 * torch.bmm(x.abs(), w.abs().transpose(1, 2)) + (x * x).sum(-1, keepdim=True)
    assert_same_winner(bmu, m.m11.distances(x), rounding_bound_nonneg(mag, w.shape[-1] + 2), largest=False, what="M1_1")
    mb = m.som_bump(m.m11, bmu=bmu)
    assert mb.min() >= 0 and min(float(c.weight.min()) for c in (m.c9, m.c10, m.c2)) >= 0  # every term >= 0
    a9, a10 = motor(bmu)
    r9, r10 = m.c9.net(mb), m.c10.net(mb)
    b9, b10 = rounding_bound_nonneg(r9, 4096), rounding_bound_nonneg(r10, 4096)
    assert_within(a9, r9, b9, "C9")
    assert_within(a10, r10, b10, "C10")
    group = lambda v: v.reshape(2, 196, 10, 3, 10).sum((-3, -1))  # noqa: E731  (M1_2's 3 actions, 100 terms each)
    act_bound = group(b9) + rounding_bound_nonneg(group(r9), 100)
    assert_same_winner(group(a9).argmax(-1), group(r9), act_bound, what="M1_2 action")
    assert_same_winner(a10.argmax(-1), r10, b10, what="C10 peak")
    (img,) = image(ss_i)
    ref = m.c2.net(ss_set[ss_i])
    bound = rounding_bound_nonneg(ref, 3100)
    assert_within(img, ref, bound, "C2")
    # the units on in the trial's image, img / max(img) >= image_threshold: the ratios differ by
    # at most (bound + ratio * bound of the max) / (max - that bound), + 1 ulp for each division.
    # With random weights every unit is above the threshold; the median splits them as well
    top, top_bound = ref.amax(-1, keepdim=True), bound.amax(-1, keepdim=True)
    ratio = ref / top
    margin = (bound + ratio * top_bound) / (top - top_bound) + cast_bound(ratio)
    for level in (m.e.image_threshold, float(ratio.median())):
        assert_same_threshold(img / img.amax(-1, keepdim=True), ratio, level, margin, "C2 image")
    assert m._lookups()[2] is motor  # built once per set of weights
    m.c9.weight.add_(0.0)
    assert m._lookups()[2] is not motor  # rebuilt after the weights change


@pytest.fixture(scope="module")
def compact_trained():
    """(settings, a model of 2 participants fitted on random images, its compact checkpoint),
    shared by the compact checkpoint's tests below (each one builds its own models to load into)."""
    e = Exp2Config(som=SomParams(iterations=30, cutoff=0.01, cluster_sigma=1.0), hebb_steps=60, c5_epochs=1)
    g = torch.Generator().manual_seed(3)
    images = {(o, a): (torch.rand(1024, generator=g) > 0.8).float() for o in (0, 1) for a in ANGLES}
    m = MotorRotationModel(e, 2, 0)
    m.fit(images)
    return e, m, m.compact_state()


def _saved(tmp_path, state) -> Path:
    path = tmp_path / "checkpoints" / "model.pt"
    path.parent.mkdir(exist_ok=True)
    torch.save(state, path)
    return path


def test_compact_checkpoint_round_trip_is_bit_exact(tmp_path, compact_trained):
    """The checkpoint written by training holds the trainer's factors, not the weights; loading
    forms every weight again by the trainer's own products: in the same process (the same kernels
    on the same shapes, at the same thread count) every state tensor comes back bit for bit."""
    from types import SimpleNamespace

    from neuroimagery.experiments.chapter5.protocol import load_model

    e, m, _ = compact_trained
    ref = m.state_dict()
    path = _saved(tmp_path, m.compact_state())
    assert path.stat().st_size < sum(v.numel() * v.element_size() for v in ref.values()) / 5
    loaded = load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e).state_dict()
    assert loaded.keys() == ref.keys()
    for k, v in ref.items():
        assert loaded[k].dtype == v.dtype and torch.equal(loaded[k], v), k


def test_compact_checkpoint_allows_one_rounding_and_refuses_twice_its_bound(compact_trained):
    """The check on load allows for the rounding of another CPU or thread count (probe rows one ulp
    off load) and no more (a probe row off by twice the rounding bound is refused)."""
    from neuroimagery.models.factor_checkpoint import PROBE_ROWS, probe_bound

    e, _, ck = compact_trained
    ulp = {k: torch.nextafter(v, torch.full_like(v, float("inf"))) for k, v in ck["probe"].items()}
    MotorRotationModel(e, 2, 0).load_compact_state({**ck, "probe": ulp})  # as another CPU may round them
    init = MotorRotationModel(e, 2, 0).state_dict()
    first = {}
    for k, f in ck["factors"].items():
        first.setdefault(f["kind"], k)
    for k in first.values():  # one entry of a weight of each kind off by twice its bound
        far = ck["probe"][k].clone()
        far[0, 0, 0] += 2 * float(probe_bound(ck["factors"][k], init[k][:, PROBE_ROWS], ck["probe"][k])[0, 0, 0])
        with pytest.raises(ValueError, match=re.escape(f"more than float rounding ({k})")):
            MotorRotationModel(e, 2, 0).load_compact_state({**ck, "probe": {**ck["probe"], k: far}})


def test_compact_checkpoint_of_other_settings_or_format_is_refused_and_a_full_one_loads(tmp_path, compact_trained):
    """An unknown format, or factors that do not rebuild the saved weights (other settings), fail
    with the file named. A full state_dict checkpoint still loads."""
    from types import SimpleNamespace

    from neuroimagery.core.errors import UserInputError
    from neuroimagery.experiments.chapter5.protocol import load_model

    e, m, ck = compact_trained
    path = _saved(tmp_path, ck)
    # other settings draw other initial weights: the rebuilt weights would differ, and loading says so
    with pytest.raises(UserInputError, match="model.pt.*differ"):
        load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, replace(e, init_high=0.2))
    with pytest.raises(ValueError, match="unknown checkpoint format 'x'"):
        MotorRotationModel(e, 2, 0).load_compact_state({**m.compact_state(), "format": "x"})
    torch.save({"format": "neuroimagery.exp2.factors/999", "participants": 2}, path)
    with pytest.raises(UserInputError, match=r"model\.pt: unknown format 'neuroimagery\.exp2\.factors/999'"):
        load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e)
    ref = m.state_dict()
    torch.save({"state_dict": ref, "participants": 2}, path)  # the full form of earlier checkpoints
    loaded = load_model(SimpleNamespace(seed=0), tmp_path, MotorRotationModel, e).state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in ref.items())


def test_summary_counts_the_participants_of_a_loaded_checkpoint(tmp_path):
    """checkpoint=DIR tests the loaded model's participants; another `participants` is refused by name."""
    from neuroimagery.core import manifest as mf
    from neuroimagery.config import experiment, validate
    from neuroimagery.core.errors import UserInputError
    from neuroimagery.app.run import RunDir, evaluate

    small = ("experiment.som.iterations=30", "experiment.hebb_steps=60", "experiment.c5_epochs=1", "logger=none")
    e = Exp2Config(som=SomParams(iterations=30, cutoff=0.01, cluster_sigma=1.0), hebb_steps=60, c5_epochs=1)
    g = torch.Generator().manual_seed(3)
    m = MotorRotationModel(e, 1, 0)
    m.fit({(o, a): (torch.rand(1024, generator=g) > 0.8).float() for o in (0, 1) for a in ANGLES})
    conf = validate(_cfg("participants=1", *small))
    tr = RunDir(tmp_path / "tr", conf, manifest=mf.build(conf, experiment("exp2")))
    tr.save_checkpoint("model", m.compact_state())
    tr.close()  # a finished training run: complete, its lock released
    with pytest.raises(UserInputError, match="participants 1 \\(stored\\) vs 3"):
        evaluate(_cfg("participants=3", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    s = evaluate(_cfg("participants=1", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    assert s["participants"] == 1 and s["tests"]["all/none"]["n_trials"] == 196


@pytest.fixture(scope="module")
def fitted_on_l():
    """(config, set L, two participants trained on it briefly), for both conditions below."""
    from neuroimagery.config import validate
    from neuroimagery.experiments.exp2 import protocol as exp2
    from neuroimagery.experiments.chapter5.protocol import image_table
    from neuroimagery.vision.stimulus_sets import get_stimulus_set

    cfg = validate(_cfg("participants=2", "logger=none", "experiment.som.iterations=30", "experiment.hebb_steps=60",
                        "experiment.c5_epochs=1"))
    sset = get_stimulus_set("L")
    model = MotorRotationModel(exp2._e(cfg), 2, 0)
    model.fit(image_table(cfg, sset, exp2.ANGLES))
    return cfg, sset, model.eval()


@pytest.mark.parametrize("condition", ["none", "match"])
def test_answers_do_not_read_labels(monkeypatch, condition, fitted_on_l):
    """The items' labels (objects, angles) shuffled after the protocol has chosen them, each trial's
    images kept: the model's answers, RTs and steps are unchanged (the rotation is scored against the
    labels outside the model)."""
    import pandas as pd
    from support_labels import answers

    from neuroimagery.experiments.exp2 import protocol as exp2

    cfg, sset, model = fitted_on_l
    base = pd.DataFrame(exp2.run_test(cfg, model, sset, "all", condition)[0])
    objs, angles = exp2.objects_of(sset), list(exp2.ANGLES)
    images = exp2.edge_maps
    true_items = [(o, a) for o in objs for a in angles]
    monkeypatch.setattr(exp2, "objects_of", lambda s: objs[::-1])  # object labels swapped
    monkeypatch.setattr(exp2, "ANGLES", angles[3:] + angles[:3])  # angle labels moved round
    monkeypatch.setattr(exp2, "edge_maps", lambda c, s, items: images(c, s, true_items))  # the images as chosen
    shuffled = pd.DataFrame(exp2.run_test(cfg, model, sset, "all", condition)[0])
    assert (shuffled["rotated_angle"] != base["rotated_angle"]).any()
    assert (shuffled["target_object"] != base["target_object"]).any()
    pd.testing.assert_frame_equal(answers(shuffled), answers(base))
