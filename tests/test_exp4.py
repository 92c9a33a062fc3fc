"""Experiment 4: config checks, exact fast paths, batched == solo, an end-to-end quick run."""
import copy
import json

import pandas as pd
import pytest
import torch
from conftest import make_cfg

from neuroimagery.config import validate
from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.experiments.exp4.config import Exp4Config
from neuroimagery.experiments.chapter6 import protocol as pc
from neuroimagery.nn import AllToAll, Delta
from neuroimagery.nn.binary import binary_matmul
from neuroimagery.app.run import evaluate


def _cfg(*overrides, quick=True):
    cfg = validate(make_cfg("experiment=exp4", *overrides))
    cfg.preset = "quick" if quick else "full"
    return cfg


def test_config_rejects_bad_values():
    from neuroimagery.models.rotation_embodied import EmbodiedLcaParams, EmbodiedPpcParams

    with pytest.raises(ValueError, match=r"experiment\.lca\.k"):
        Exp4Config(lca=EmbodiedLcaParams(k=-0.1))
    with pytest.raises(ValueError, match="noise_tests"):
        Exp4Config(noise_tests=["nope"])
    with pytest.raises(ValueError, match=r"experiment\.ppc\.angles"):
        Exp4Config(ppc=EmbodiedPpcParams(angles=[30.0, 0.0]))


def test_binary_matmul_equals_bmm():
    g = torch.Generator().manual_seed(0)
    W = torch.rand(3, 7, 11, generator=g)
    x = (torch.rand(3, 5, 11, generator=g) > 0.6).float()
    x[1, 2] = 0  # an empty input
    ref = torch.bmm(x, W.transpose(1, 2))
    assert torch.allclose(binary_matmul(W.transpose(1, 2).contiguous(), x), ref, atol=1e-6)


def test_sparse_delta_equals_connection_learn():
    g = torch.Generator().manual_seed(1)
    X = (torch.rand(2, 12, 9, generator=g) > 0.7).float()
    Y = torch.rand(2, 12, 6, generator=g)
    a = AllToAll(9, 6, participants=2, seed=3, rules=Delta(0.1))
    b = AllToAll(9, 6, participants=2, seed=3, rules=Delta(0.1))
    a.learn(X, None, sequence=True, batch=4, target=Y)  # the binary kernel (0/1 inputs, CPU)
    assert a.learnt_factors is None
    for s in range(0, 12, 4):
        x = X[:, s:s + 4]
        b.learn(pre=x, post=b(x), target=Y[:, s:s + 4])
    assert not torch.equal(a.weight, AllToAll(9, 6, participants=2, seed=3).weight)  # learning changed it
    assert torch.allclose(a.weight, b.weight, atol=1e-5)


def test_batched_participants_equal_solo_runs():
    cfg = _cfg("participants=2", "logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100")
    both = exp4.train_model(cfg, [0, 1])
    solo = exp4.train_model(cfg, [1])
    assert torch.allclose(both.fm[0].weight[1], solo.fm[0].weight[0], atol=1e-5)
    assert torch.allclose(both.c16.weight[1], solo.c16.weight[0], atol=1e-5)
    eye = pc.make_eye(cfg)
    bank = pc.StimulusBank.build(eye, pc.stimulus_set(cfg, "exp4-A", False), 32)
    table = pc.trial_table(bank, "recog", "noise-mismatch").iloc[:40]
    tgt = bank.maps[torch.as_tensor(table["target_row"].to_numpy().copy())]
    rot = bank.maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())]
    from neuroimagery.nn import seeding
    ob = both.run(tgt.expand(2, -1, -1), rot.expand(2, -1, -1), seeding.participant_generators(0, [0, 1], 100),
                  proprioception="mismatch", noise=True)
    os_ = solo.run(tgt.unsqueeze(0), rot.unsqueeze(0), seeding.participant_generators(0, [1], 100),
                   proprioception="mismatch", noise=True)
    for k in ("answer", "rt", "rotation_steps"):
        assert torch.equal(ob[k][1], os_[k][0]), k


@pytest.fixture(scope="module")
def small_model():
    cfg = _cfg("participants=2", "logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100")
    bank = pc.StimulusBank.build(pc.make_eye(cfg), pc.stimulus_set(cfg, "exp4-A", False), 32)
    return bank, exp4.train_model(cfg, [0, 1])


@pytest.mark.parametrize("prop,noise,test_keys", [("none", False, False), ("mismatch", True, False), ("match", True, True)])
def test_fused_trial_equals_the_plain_trial(small_model, prop, noise, test_keys):
    """run() (all rows fused, binary products) against run_plain() (one trial at a time, dense
    products, the equations in order): the same answers, cycles, steps and rotations; also with a
    softmax PPCp winner (a test setting: the trained model is the same)."""
    from dataclasses import replace

    from neuroimagery.models.rotation_embodied_plain import run_plain
    from neuroimagery.nn import seeding

    bank, model = small_model
    if test_keys:
        model = copy.copy(model)
        model.p = replace(model.p, posture=replace(model.p.posture, tau=0.1))
    table = pc.trial_table(bank, "recog", "none").iloc[::13].iloc[:8]
    tgt = bank.maps[torch.as_tensor(table["target_row"].to_numpy().copy())].expand(2, -1, -1)
    rot = bank.maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())].expand(2, -1, -1)
    gens = lambda: seeding.participant_generators(0, [0, 1], 100)  # noqa: E731
    fused = model.run(tgt, rot, gens(), proprioception=prop, noise=noise)
    plain = run_plain(model, tgt, rot, gens(), proprioception=prop, noise=noise)
    assert int(fused["rotation_steps"].sum()) > 0  # the trials do rotate
    for k in ("answer", "rt", "rotation_steps", "rotations", "decided", "rotation_deg"):
        assert torch.equal(fused[k].to(plain[k].dtype), plain[k]), k


def test_end_to_end_quick_run_writes_results(tmp_path):
    cfg = _cfg("participants=1", "logger.sample_trials=1", "experiment.quick.fm_images=2000")
    summary = evaluate(cfg, out_dir=tmp_path)
    for f in ("trials.csv", "summary.json", "report.md", "checkpoints/exp4.pt", "figures/fig6_9a_rt.png",
              "figures/fig6_12a_recog.png", "figures/fig6_10a_rt.png", "figures/fig6_11a_rt.png"):
        assert (tmp_path / f).exists(), f
    events = list((tmp_path / "tb").glob("events.out.tfevents.*"))
    assert len(events) == 1
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    ea = EventAccumulator(str(tmp_path / "tb"), size_guidance={"images": 0, "scalars": 0})
    ea.Reload()
    # training curves over their own steps: the forward models' delta rule and the posture maps' Kohonen rule
    curves = {t: len(ea.Scalars(t)) for t in ea.Tags()["scalars"] if t.startswith("train/")}
    assert sum(t.endswith("/squared_error") and n >= 10 for t, n in curves.items()) == 3, curves
    assert any(t.startswith("train/som/") and t.endswith("label_distance") and n >= 10 for t, n in curves.items())
    # the sample trial (chosen among those that rotated and decided), an image series over its rotation steps
    tag = next(t for t in ea.Tags()["images"] if t.startswith("recog/none/") and t.endswith("/POCi"))
    assert len(ea.Images(tag)) >= 3 and [e.step for e in ea.Images(tag)][:3] == [1, 2, 3]
    assert "_hparams_/experiment" in ea.PluginTagToContent("hparams")
    report = (tmp_path / "report.md").read_text()
    captions = [ln for ln in report.splitlines() if ln.startswith("*Figure ")]
    assert [int(c.split()[1].rstrip(".")) for c in captions] == list(range(1, len(captions) + 1))
    assert captions[0].startswith("*Figure 1. (Fig. 6.9a)") and all("Thesis:" in c for c in captions)
    assert "Holm" in report and "participant as the unit" in report
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["experiment"] == "exp4" and s["participants"] == 1
    keys = {f"{t}/{c}" for t in ("recog", "gen1", "gen2") for c in ("none", "match", "mismatch")}
    keys |= {f"{t}/noise-{c}" for t in ("recog", "gen1") for c in ("none", "match", "mismatch")}
    assert set(s["tests"]) == keys
    df = pd.read_csv(tmp_path / "trials.csv")
    assert len(df) == 144 * len(keys)
    # modelling claims on this reduced (1 participant, 1 object per set) run
    t = s["tests"]
    assert t["recog/none"]["rt_r"] > 0  # the direction the thesis states (RT rises with disparity), not a level
    assert t["recog/none"]["correct_rate"] > t["gen2/none"]["correct_rate"]
    assert t["recog/mismatch"]["rt_mean"] > t["recog/none"]["rt_mean"]
    rt_n = s["rt_by_rotation_steps"]
    assert all(10 * int(n) <= v <= 10 * int(n) + 10 for n, v in rt_n.items() if int(n) <= 3)
    assert summary["forward_model_iou"]["gen1"]["1"] > 0.5


def _check_full_protocol(s):
    """The claims of the full protocol, fixed from the thesis (SPEC sec. 6), not from a run.

    Significance (p < 0.01) is asserted only for the incongruent wrist without noise, a large
    effect the thesis states outright. For congruent proprioception under noise the thesis claims
    shorter RT "at high disparity"; "high disparity" is the subset the experiment code fixes
    in advance (``_stats``: disparity >= half the largest, i.e. 90, 120 and 150 deg). This test
    asserts the DIRECTION ONLY there, for Recog, and likewise that noise slows the model there:
    these effects are a few cycles, and any p threshold (the reference run gives p = 0.09 and
    0.03) would be picked to fit a known run. Per-disparity bands and the whole-range comparison
    are reported (report.md), not asserted. Not asserted because the model does not reproduce
    them (docs/exp4.md, "What differs from the thesis"): the congruent gain on correct rates, the
    Gen1 RT gain over disparities >= 75, and the shorter RT of a congruent wrist under noise at
    high disparity (seed 0: 39.53 against 39.52 cycles; no gain on any of seeds 0-4: with the
    wrist signal cut to [0, 1] together with the bump and the noise, the congruent unit is already
    the bump's winner).
    """
    t = s["tests"]
    assert t["recog/none"]["rt_r"] > 0  # the direction the thesis states (RT rises with disparity), not a level and t["gen1/none"]["rt_r"] >= 0.9
    assert t["recog/none"]["correct_rate"] > t["gen2/none"]["correct_rate"]
    assert t["gen1/none"]["correct_rate"] > t["gen2/none"]["correct_rate"]
    # incongruent proprioception slows the rotation down and costs accuracy on the trained shapes
    st = s["statistics"]["recog:mismatch-vs-none"]
    assert st["rt"]["mean_a"] > st["rt"]["mean_b"] and st["rt"]["p"] < 0.01
    assert st["correct"]["rate_a"] < st["correct"]["rate_b"]
    # RT is about 10 accumulator cycles per rotation step
    assert all(10 * int(n) <= v <= 10 * int(n) + 10 for n, v in s["rt_by_rotation_steps"].items() if int(n) <= 3)
    # congruent proprioception: no gain without noise (ceiling) ...
    st = s["statistics"]["recog:match-vs-none"]
    assert st["rt"]["p"] > 0.05
    # ... with noise, at high disparity (the pre-defined subset), direction only: noise slows
    # the model down
    st = s["statistics"]["recog:noise-none-vs-none:disparity>=75"]
    assert st["rt"]["mean_a"] > st["rt"]["mean_b"]


@pytest.mark.slow
def test_full_protocol(tmp_path):
    """Full protocol, 10 participants; the claims and why some are direction-only: _check_full_protocol."""
    _check_full_protocol(evaluate(_cfg("logger=none", quick=False), out_dir=tmp_path))


def _tiny_model(**over):
    from neuroimagery.models.rotation_embodied import RotationEmbodied
    from neuroimagery.nn import seeding

    from neuroimagery.models.params import ForwardModelParams
    from neuroimagery.models.rotation_embodied import EmbodiedPostureParams, EmbodiedPpcParams

    post = {"tau": over.pop("posture_tau")} if "posture_tau" in over else {}
    e = Exp4Config(map_size=8, fm=ForwardModelParams(dot_inner=4), posture=EmbodiedPostureParams(**post),
                        ppc=EmbodiedPpcParams(), **over)
    return RotationEmbodied(e, seeding.participant_generators(0, [0], stream=0))


def test_congruent_wrist_signal_against_noise():
    """Under PPCp noise, a congruent wrist signal added before the clip saturates at 1 with the bump:
    it does not keep the model at an aligned posture."""
    from neuroimagery.nn.functional import gain_field, softmax_probabilities

    m = _tiny_model()
    nu, R = 6, 4000
    g = torch.Generator().manual_seed(0)
    j = torch.full((R,), 2)
    u = torch.rand(R, nu, generator=g)
    ppct = m.ppc.encode(j.float())

    def p_stay(prop):
        ppcp = m.ppcp_code(j, prop, u)
        am = m.c20(gain_field(ppct, ppcp).reshape(R, nu * nu))
        return float(softmax_probabilities(am, 0.1)[:, 1].mean()), ppcp

    none, pn = p_stay("none")
    match, pm = p_stay("match")
    assert pn.max() <= 1.0 and pn.min() >= 0.0  # noise is clipped to [0, 1]
    assert 0.4 < none < 0.9  # the noise alone makes the model leave an aligned posture often
    assert pm.max() <= 1.0 and match < none + 0.1  # the congruent signal is lost in the [0, 1] ceiling


def test_posture_winner_is_uncertain_only_for_flat_potentials():
    m0, m1 = _tiny_model(), _tiny_model(posture_tau=0.1)
    sharp = torch.tensor([[0.2, 0.3, 1.0, 0.4, 0.3, 0.2]]).expand(2000, -1)
    flat = torch.tensor([[0.95, 0.97, 1.0, 0.96, 0.98, 0.94]]).expand(2000, -1)
    u = torch.rand(2000, generator=torch.Generator().manual_seed(1))
    assert torch.equal(m0.posture_winner(flat, u), torch.full((2000,), 2))  # eq. 6.14: arg-max
    assert float((m1.posture_winner(sharp, u) == 2).float().mean()) > 0.99
    assert float((m1.posture_winner(flat, u) == 2).float().mean()) < 0.4


def test_rt_by_required_steps_groups_by_disparity_not_by_steps_made():
    df = pd.DataFrame({"test": ["recog"] * 5 + ["gen1"] * 2, "condition": ["none"] * 4 + ["match", "none", "none"],
                       "decided": [True, True, True, False, True, True, True],
                       "disparity": [0, 60, 60, 60, 60, 30, 60], "rotation_steps": [0, 2, 4, 19, 2, 3, 2],
                       "rt": [5, 23, 44, 200, 25, 38, 27]})
    req = exp4._rt_vs_required_steps(df, 30.0)
    # undecided trials and other conditions are left out; the detour trial (4 steps for a 60-deg pair) counts at n = 2
    assert req["all"] == {"0": 5.0, "1": 38.0, "2": round((23 + 44 + 27) / 3, 2)}
    assert req["recog"] == {"0": 5.0, "2": 33.5} and req["gen1"] == {"1": 38.0, "2": 27.0}
    assert exp4._rt_vs_steps(df) == {"0": 5.0, "2": 25.0, "3": 38.0, "4": 44.0}


# one tiny participant: the condition comparisons run on nearly equal RTs, which scipy warns about
@pytest.mark.filterwarnings("ignore:Precision loss occurred in moment calculation:RuntimeWarning")
def test_summary_counts_the_participants_of_a_loaded_checkpoint(tmp_path):
    """checkpoint=DIR: the summary counts the loaded model's participants, another count is refused.
    (The tests build 2 looks per item and stop a trial after 3 rotation steps: what is counted does
    not depend on either.)"""
    from neuroimagery.core.errors import UserInputError
    from neuroimagery.app.run import train

    small = ("logger=none", "experiment.quick.fm_images=300", "experiment.posture.iterations=100", "experiment.noise_tests=[]",
             "experiment.percept.looks=2", "experiment.selection.max_steps=3")
    train(_cfg("participants=1", *small), out_dir=tmp_path / "tr")
    with pytest.raises(UserInputError, match="participants 1 \\(stored\\) vs 3"):
        evaluate(_cfg("participants=3", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    s = evaluate(_cfg("participants=1", f"checkpoint={tmp_path / 'tr'}", *small), out_dir=tmp_path / "ev")
    assert s["participants"] == 1
    assert "rt_by_required_steps" in s and "all" in s["rt_by_required_steps"]
    assert "n steps required" in (tmp_path / "ev" / "report.md").read_text()


def test_answers_do_not_read_labels(monkeypatch):
    """Shuffling every label column of the chosen trials, images kept, changes no answer or RT."""
    from support_labels import assert_run_tests_read_no_labels

    cfg = _cfg("participants=2", "logger=none", "experiment.fm.images=300", "experiment.posture.iterations=100",
               "experiment.noise_tests=[recog]", quick=False)
    assert_run_tests_read_no_labels(monkeypatch, exp4, cfg, exp4.train_model(cfg, [0, 1]))
