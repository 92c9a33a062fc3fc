"""Experiment 3: config checks, batched == solo, an end-to-end quick run."""
import json
import math

import pytest
import torch
from conftest import make_cfg

from neuroimagery.config import validate
from neuroimagery.experiments.exp3 import protocol as exp3
from neuroimagery.experiments.exp3.config import Exp3Config
from neuroimagery.experiments.chapter6 import protocol as pc
from neuroimagery.nn import seeding
from neuroimagery.app.run import evaluate


def _cfg(*overrides, quick=True):
    cfg = validate(make_cfg("experiment=exp3", *overrides))
    cfg.preset = "quick" if quick else "full"
    return cfg


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="match_threshold"):
        Exp3Config(match_threshold=2.0)
    with pytest.raises(ValueError, match="m1_centre_sigma"):
        Exp3Config(m1_centre_sigma=0.0)


def test_m1_2_prefers_the_triangle_holding_the_activity():
    cfg = _cfg("participants=1", "logger=none")
    model = exp3._model(cfg, [0])
    m = torch.zeros(1, 3, 4, 4)
    m[0, 0, 1, 1] = 1.0  # current == desired posture: diagonal -> n2
    m[0, 1, 0, 2] = 1.0  # upper-right -> n3
    m[0, 2, 3, 0] = 1.0  # lower-left -> n1
    n = model.m1_2(m.reshape(1, 3, 16))
    assert n.argmax(-1).tolist() == [[1, 2, 0]]
    assert (n.sort(-1).values[..., 1] < 0.4).all()  # the other units fall well below the winner


def test_flat_posture_codes_stop_the_rotation():
    """Thesis 6.1.3: codes with no clear orientation make M1_1 activate its central units -> n2."""
    flat = torch.full((1, 1, 4), 1.0)
    m11 = (flat.unsqueeze(-1) * flat.unsqueeze(-2)).reshape(1, 1, 16)  # eq. 6.1 gain field
    spread = exp3._model(_cfg("participants=1", "logger=none"), [0]).m1_2(m11)  # rule R7
    # flat codes: offsets (SS - PMC_1 unit) over the 16 cells have variance 2.5; the triangles' centres lie 5/3
    # from the diagonal, so the turns are exp(-(5/3)^2 / (2 (0.5^2 + 2.5))), n2 still the most active
    assert spread.argmax(-1).item() == 1
    assert torch.allclose(spread[0, 0, [0, 2]], torch.tensor(math.exp(-(5 / 3) ** 2 / (2 * (0.25 + 2.5)))), atol=1e-4)


def test_the_full_protocol_answers_every_pair():
    """Full protocol (192 pairs per test), three participants: one answered row per pair. How often
    the answers are right is an outcome (docs/exp3.md), not a test."""
    cfg = _cfg("participants=3", "logger=none", quick=False)
    df, _, _ = exp3.run_tests(cfg, exp3.train_model(cfg, [0, 1, 2]))
    assert len(df) == 3 * 3 * 192
    assert set(df["test"]) == {"recog", "gen1", "gen2"}
    assert df["correct"].notna().all()


def test_match_tolerance_covers_a_one_unit_shift_only():
    cfg = _cfg("participants=1", "logger=none")
    model = exp3._model(cfg, [0])
    img = torch.zeros(32, 32)
    img[10, 5:25] = 1.0
    shifted, two, far = torch.roll(img, 1, 0), torch.roll(img, 2, 0), torch.roll(img, 3, 0)
    t = img.reshape(1, 1, -1)
    assert model.p.match_tolerance == 1  # the default: PP_2 read as a population code of reach 1
    model.p.match_tolerance = 0  # the option: the literal one-to-one C8
    assert model.uncovered(t, t).sum() == 0
    assert model.uncovered(t, shifted.reshape(1, 1, -1)).sum() == img.sum()
    model.p.match_tolerance = 1
    assert model.uncovered(t, shifted.reshape(1, 1, -1)).sum() == 0
    assert model.uncovered(t, two.reshape(1, 1, -1)).sum() == img.sum()  # tolerance 2 would cover it
    assert model.uncovered(t, far.reshape(1, 1, -1)).sum() == img.sum()


def test_batched_participants_equal_solo_runs():
    cfg = _cfg("participants=2", "logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100")
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


def test_batched_trial_equals_the_plain_trial():
    """run() (all trials batched, C6 as sums of active weight rows) against run_plain() (one trial at
    a time, dense products, the equations in order): the same answers, steps and angles."""
    from neuroimagery.models.rotation_generalising_plain import run_plain

    cfg = _cfg("participants=2", "logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100")
    model = exp3.train_model(cfg, [0, 1])
    bank = pc.StimulusBank.build(pc.make_eye(cfg), pc.stimulus_set(cfg, "exp3-a", False), 32)
    table = pc.trial_table(bank, "recog", "none").iloc[::5].iloc[:16]
    tgt = bank.maps[torch.as_tensor(table["target_row"].to_numpy().copy())].expand(2, -1, -1)
    rot = bank.maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())].expand(2, -1, -1)
    batched = model.run(tgt, rot, seeding.participant_generators(0, [0, 1], 100))
    plain = run_plain(model, tgt, rot, seeding.participant_generators(0, [0, 1], 100))
    assert int(batched["rotation_steps"].sum()) > 0  # the trials do rotate
    for k in ("answer", "rotation_steps", "rotation_deg"):
        assert torch.equal(batched[k], plain[k]), k


def test_end_to_end_quick_run_writes_results(tmp_path):
    cfg = _cfg("participants=2", "logger.sample_trials=1", "experiment.quick.fm_images=1500")
    evaluate(cfg, out_dir=tmp_path)
    for f in ("trials.csv", "summary.json", "report.md", "checkpoints/exp3.pt", "figures/fig6_5a_rt.png"):
        assert (tmp_path / f).exists(), f
    s = json.loads((tmp_path / "summary.json").read_text())
    assert set(s["tests"]) == {"recog/none", "gen1/none", "gen2/none"}
    assert s["tests"]["recog/none"]["n_trials"] == 2 * 64


@pytest.mark.slow
def test_full_protocol(tmp_path):
    s = evaluate(_cfg("logger=none", quick=False), out_dir=tmp_path)
    t = s["tests"]
    assert t["recog/none"]["n_trials"] == 1920
    # RT (rotation steps) grows linearly with disparity for the trained and the Gen-I shapes
    assert t["recog/none"]["rt_r"] >= 0.9 and t["gen1/none"]["rt_r"] >= 0.9
    # at 0 deg Recog and Gen-I hardly rotate
    assert t["recog/none"]["rt_by_disparity"]["0"] < 0.6 and t["gen1/none"]["rt_by_disparity"]["0"] < 0.6
    # error rates ordered Recog < Gen-I < Gen-II
    assert t["recog/none"]["error_rate"] < t["gen1/none"]["error_rate"] < t["gen2/none"]["error_rate"]
    # Gen-II (flat posture codes) stops early: fewer rotations than Recog at 90 and 135 deg
    for d in ("90", "135"):
        assert t["gen2/none"]["rt_by_disparity"][d] < t["recog/none"]["rt_by_disparity"][d]
    # no set is answered at chance
    assert max(t["recog/none"]["error_rate"], t["gen1/none"]["error_rate"]) < 0.35


def test_rotated_ok_compares_orientations_modulo_360():
    """A rotation that ends aligned after turning the long way round counts as rotated."""
    import numpy as np
    import pandas as pd

    assert pc.angle_aligned([315.0, -45.0, 360.0, 405.0, 0.0, 45.0, 180.0], [-45.0, 315.0, 0.0, 45.0, 0.0, -45.0, -180.0]).tolist() \
        == [True, True, True, True, True, False, True]
    table = pd.DataFrame({"test": "recog", "condition": "none", "target_object": "o", "target_angle": [-45.0, -45.0, 90.0],
                          "target_appearance": "basic", "rotated_object": "o", "rotated_angle": [90.0, 90.0, 90.0],
                          "rotated_appearance": "basic", "same": True, "disparity": [135, 135, 0],
                          "target_row": 0, "rotated_row": 0})
    out = {"answer": torch.zeros(1, 3, dtype=torch.long), "rt": torch.tensor([[5.0, 3.0, 0.0]]),
           "rotation_steps": torch.tensor([[5, 3, 0]]),
           "rotation_deg": torch.tensor([[225.0, -135.0, 0.0]])}  # 90 + 225 = 315 = -45 (mod 360)
    df = pc.trial_rows(table, out, [0])
    assert df["rotated_ok"].tolist() == [True, True, True]
    out["rotation_deg"] = torch.tensor([[180.0, -90.0, 45.0]])
    assert not pc.trial_rows(table, out, [0])["rotated_ok"].any()
    assert np.issubdtype(df["rotated_ok"].dtype, np.bool_)


def test_summary_counts_the_participants_of_a_loaded_checkpoint(tmp_path):
    from neuroimagery.core.errors import UserInputError
    from neuroimagery.app.run import train

    small = ("logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100")
    train(_cfg("participants=2", *small), out_dir=tmp_path / "tr")
    with pytest.raises(UserInputError, match="participants 2 \\(stored\\) vs 5"):
        evaluate(_cfg("participants=5", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    s = evaluate(_cfg("participants=2", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    assert s["participants"] == 2
    assert s["tests"]["recog/none"]["n_trials"] == 2 * 64
    assert (tmp_path / "ev" / "report.md").read_text().count("2 simulated participants") == 1


def test_answers_do_not_read_labels(monkeypatch):
    """Shuffling every label column of the chosen trials, images kept, changes no answer or RT."""
    from support_labels import assert_run_tests_read_no_labels

    cfg = _cfg("participants=2", "logger=none", "experiment.fm.images=300", "experiment.posture.iterations=100",
               quick=False)
    assert_run_tests_read_no_labels(monkeypatch, exp3, cfg, exp3.train_model(cfg, [0, 1]))
