"""Experiment 5: brain (C1-C4) and the Fig. 7.5 / 7.6 algorithms (the configuration: test_exp5_config.py;
the run: test_exp5_run.py).

Fast tests use the STAND-IN environment of ``tests/support_tool_env.py`` (a 2-D kinematic toy, not
the robot); the pybullet world is exercised only by the slow test at the end.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))
from support_tool_env import StandInToolEnv  # noqa: E402

from neuroimagery.models.tool_use import (EVENTS, AcquisitionParams, Outcomes,  # noqa: E402
                                          SequencingParams, ToolUseBrain, acquire_skills, build_brain, sequence_trial)


def small_acq(**kw):
    base = dict(max_epochs=3, explore_max_rollouts=200, c3_repeats=5, c1_repeats=3, c2_repeats=3)
    base.update(kw)
    return AcquisitionParams(**base)


# ---------------------------------------------------------------------------------- brain
def test_c1_training_changes_only_the_trained_unit():
    b = ToolUseBrain((6, 8))
    x = torch.zeros(2, 6, 8)
    x[0, 2, 3] = x[1, 4, 5] = 1.0
    b.train_c1(x, unit=3, signal=0.7, times=200)
    aff = b.affordance(x)
    assert aff[3] == pytest.approx(0.7, abs=1e-3)
    assert torch.count_nonzero(aff) == 1
    b.train_c1(x, unit=5, signal=0.2, times=200)
    assert b.affordance(x)[3] == pytest.approx(0.7, abs=1e-3)  # unit 3 kept what it learnt


def test_q_update_matches_eq_7_1_by_hand():
    b = ToolUseBrain((2, 2), q_eta=0.1, q_gamma=0.8)
    x0, x1 = torch.zeros(2, 2, 2), torch.zeros(2, 2, 2)
    x0[0, 0, 0] = 1.0
    x1[1, 1, 1] = 1.0
    b.c4.weight[0, 4, 7] = 0.5  # q(x1, unit 4) = 0.5 = qMax_t
    b.train()
    b.q_update(x0, unit=2, reward=1.0, x1=x1, done=False)
    # dw_{2,i} = eta (r + gamma qMax_t - qWin_{t-1}) x_{i,t-1}; qWin = 0
    assert b.c4.weight[0, 2, 0].item() == pytest.approx(0.1 * (1.0 + 0.8 * 0.5))
    assert torch.count_nonzero(b.c4.weight[0, 2]) == 1


def test_imagination_returns_the_trained_outcome_for_the_intended_action():
    b = ToolUseBrain((6, 8), c3_eta=0.5)
    b.train()
    g = torch.Generator().manual_seed(0)
    sit = torch.zeros(2, 6, 8)
    sit[0, 1, 1] = sit[1, 5, 5] = 1
    out_a, out_b = torch.zeros(2, 6, 8), torch.zeros(2, 6, 8)
    out_a[0, 4, 1] = 1
    out_b[0, 0, 7] = 1
    b.train_c3(sit, unit=1, posture=1, outcome=out_a, times=40, generator=g)
    b.train_c3(sit, unit=2, posture=1, outcome=out_b, times=40, generator=g)
    assert torch.allclose(b.imagine(sit, 1), out_a, atol=1e-3)
    assert torch.allclose(b.imagine(sit, 2), out_b, atol=1e-3)
    assert torch.equal(b.imagine(sit, 7), sit)  # an untrained primitive imagines no change


def test_practised_recall_recognises_a_situation_where_nothing_succeeded():
    """Only the pull succeeded, from A. C3 recognises B (practised, nothing stored in C3) and
    imagines no change there; from A it imagines A's outcome."""
    g = torch.Generator().manual_seed(0)
    sit_a, sit_b = torch.zeros(2, 6, 8), torch.zeros(2, 6, 8)
    sit_a[0, 1, 1] = sit_a[1, 5, 5] = 1
    sit_b[0, 1, 1] = sit_b[1, 2, 6] = sit_b[1, 3, 6] = 1
    out_a = torch.zeros(2, 6, 8)
    out_a[0, 4, 1] = 1
    b = ToolUseBrain((6, 8), c3_eta=0.5)
    b.train()
    b.practise_in(1, sit_a)
    b.practise_in(4, sit_b)
    b.train_c3(sit_a, unit=1, posture=1, outcome=out_a, times=40, generator=g)
    assert torch.allclose(b.imagine(sit_a, 1), out_a, atol=1e-3)
    assert torch.equal(b.imagine(sit_b, 1), sit_b) and b.recall_unit(sit_b, 1) == 3 * 10 + 1
    near_a = sit_a.clone()
    near_a[1, 0, 0] = 1  # a new scene that looks like A: A's pull outcome is imagined
    assert torch.allclose(b.imagine(near_a, 1), out_a, atol=1e-3)


# ---------------------------------------------------------------------------------- algorithms
@pytest.fixture(scope="module")
def acquired():
    env = StandInToolEnv()
    brain = ToolUseBrain(env.image_shape)
    brain.train()
    # seed 2: a library whose pull works from posture 1 (the tests below need the tool-behind pull)
    lib = acquire_skills(env, ["retrieve", "touch", "west"], small_acq(), torch.Generator().manual_seed(2), brain=brain)
    assert any(s.event == "retrieve" and s.succeeds_from[0] for s in lib.skills)
    return env, brain, lib


def test_skill_acquisition_learns_only_enabled_events(acquired):
    env, brain, lib = acquired
    events = [s.event for s in lib.skills]
    assert set(events) <= {"retrieve", "touch", "west"} and len(events) == len(set(events))
    assert len(events) + len(lib.missing) == 3
    for s in lib.skills:
        assert 1 <= len(s.competence) <= 3 and all(0 <= c <= 1 for c in s.competence)
        assert s.theta.shape == (env.n_params,)
    assert len({s.unit for s in lib.skills}) == len(lib.skills)
    assert lib.explore_rollouts > 0 and lib.learn_rollouts > 0


def test_replayed_brain_equals_the_brain_trained_during_acquisition(acquired):
    env, brain, lib = acquired
    rebuilt = build_brain(env, lib, small_acq(), ToolUseBrain(env.image_shape), torch.Generator().manual_seed(0))
    assert torch.allclose(rebuilt.c1.weight, brain.c1.weight, atol=1e-5)
    assert torch.allclose(rebuilt.c2.weight, brain.c2.weight, atol=1e-5)
    assert torch.equal(rebuilt.c3_trained, brain.c3_trained)
    assert torch.equal(rebuilt.c3.som.weight, brain.c3.som.weight)  # the same mental images
    assert torch.equal(rebuilt.acquired, brain.acquired)
    assert torch.equal(rebuilt.practised_seen, brain.practised_seen) and torch.equal(rebuilt.practised, brain.practised)


def test_brain_maps_show_each_connection_of_each_skill(acquired):
    env, brain, lib = acquired
    H, W = env.image_shape
    skills = {s.name: s.unit for s in lib.skills}
    maps = brain.maps(skills)
    assert all(m.shape == (H, 2 * W) for m in maps.values())
    for name, unit in skills.items():  # toy channel on the left, tool channel on the right
        w = brain.c1.weight[0, unit].reshape(2, H, W)
        assert torch.equal(maps[f"C1/{name}"][:, :W], w[0]) and torch.equal(maps[f"C1/{name}"][:, W:], w[1])
        assert f"C4/{name}" in maps
    assert {k for k in maps if k.startswith("C2/")} == {f"C2/{e}" for e in EVENTS}
    c3 = {k for k in maps if k.startswith("C3/")}
    assert len(c3) == int(brain.c3_trained.sum()) > 0  # one mental image per trained (situation, skill)
    for k in c3:
        _, posture, name = k.split("/")
        image = brain.imagine(env.perceive(env.start(int(posture[-1]))), skills[name])
        assert torch.equal(maps[k], torch.cat([image[0], image[1]], dim=1))  # C3 run backwards gives the same image


def test_planning_child_trains_without_moving_and_reactive_child_moves(acquired):
    env, _, lib = acquired
    # C3 trained 50 times per outcome (as in the thesis), so a mental image is the outcome itself
    brain = build_brain(env, lib, small_acq(c3_repeats=50), ToolUseBrain(env.image_shape), torch.Generator().manual_seed(0))
    outcomes = Outcomes(env, {s.name: s for s in lib.skills}, env.perceive)
    g = torch.Generator().manual_seed(3)
    before, cached = env.rollouts, len(outcomes.table)
    c4 = brain.c4.weight.clone()
    planning = [sequence_trial(brain, outcomes, lib.skills, 1, "planning", True, 5, 0.1, g) for _ in range(3)]
    assert all(1 <= len(rec.actions) <= 5 for rec in planning)
    assert env.rollouts == before and len(outcomes.table) == cached  # imagined through C3 only
    assert any(any(rec.rewards) for rec in planning), "tool behind: the pull should retrieve the toy in mind"
    assert not torch.equal(c4, brain.c4.weight)  # C4 learnt from the imagined rewards
    brain.c4.weight.zero_()
    reactive = [sequence_trial(brain, outcomes, lib.skills, 1, "reactive", True, 5, 0.1, g) for _ in range(3)]
    assert env.rollouts > before or len(outcomes.table) > cached  # performed in the world
    assert all(rec.success == bool(rec.rewards[-1] > 0) for rec in reactive)
    assert any(rec.success for rec in reactive)
    assert brain.c4.weight.abs().sum() > 0  # C4 learnt from the real rewards


def test_planning_test_acts_from_the_real_scene_each_attempt(acquired):
    """A planning child's test: every attempt is performed and judged on the real scene."""
    env, _, lib = acquired
    brain = build_brain(env, lib, small_acq(), ToolUseBrain(env.image_shape), torch.Generator().manual_seed(0))
    outcomes = Outcomes(env, {s.name: s for s in lib.skills}, env.perceive)
    g = torch.Generator().manual_seed(5)
    for posture in (1, 4):
        for _ in range(5):
            rec = sequence_trial(brain, outcomes, lib.skills, posture, "planning", False, 5, 0.1, g)
            real = [outcomes.after(posture, tuple(rec.actions[:n + 1])).retrieved for n in range(len(rec.actions))]
            assert rec.rewards == [float(r) for r in real]  # rewards read from the real scenes
            assert rec.success == real[-1] and not any(real[:-1])  # stops at the first real retrieval
            assert len(rec.actions) == 5 or rec.success


def test_active_threshold_lets_only_afforded_units_compete(acquired):
    """Fig. 7.6 "select one active neuron of PMC": with a threshold, a unit whose PMC activity is at
    or below it is never chosen, and a child with no active unit does not move."""
    env, _, lib = acquired
    brain = build_brain(env, lib, small_acq(), ToolUseBrain(env.image_shape), torch.Generator().manual_seed(0))
    outcomes = Outcomes(env, {s.name: s for s in lib.skills}, env.perceive)
    units = torch.tensor([s.unit for s in lib.skills])
    x0 = outcomes.image(1, ())
    act = brain.pmc(x0)[units]
    assert act.max() > act.min(), "the stand-in's situation 1 should afford some primitives more than others"
    threshold = float((act.max() + act.min()) / 2)
    active = {s.name for s, a in zip(lib.skills, act) if a > threshold}
    g = torch.Generator().manual_seed(7)
    firsts = {sequence_trial(brain, outcomes, lib.skills, 1, "reactive", False, 1, 10.0, g,
                             active_threshold=threshold).actions[0] for _ in range(40)}
    assert firsts <= active  # even at a high temperature, only active units are drawn
    everything = {sequence_trial(brain, outcomes, lib.skills, 1, "reactive", False, 1, 10.0, g).actions[0]
                  for _ in range(40)}
    assert everything - active, "without the threshold, unafforded units are drawn too"
    c4 = brain.c4.weight.clone()
    for strategy in ("reactive", "planning"):
        idle = sequence_trial(brain, outcomes, lib.skills, 1, strategy, True, 5, 0.1, g,
                              active_threshold=float(act.max()))
        assert idle.actions == [] and not idle.success and not idle.imagined_success
    assert torch.equal(c4, brain.c4.weight)  # no move, no reward, no learning
    with pytest.raises(ValueError, match="experiment.sequencing.active_threshold"):
        SequencingParams(active_threshold=1.0)


def test_batched_c1_and_c3_updates_equal_repeated_single_steps(monkeypatch):
    g = torch.Generator().manual_seed(0)
    x = (torch.rand(2, 6, 8, generator=g) < 0.3).float()
    out = (torch.rand(2, 6, 8, generator=g) < 0.3).float()
    a, b = ToolUseBrain((6, 8)), ToolUseBrain((6, 8))
    a.c1.weight.uniform_(0, 1, generator=g)
    b.c1.weight.copy_(a.c1.weight)
    a.train_c1(x, unit=2, signal=0.4, times=7)
    for _ in range(7):
        b.train_c1(x, unit=2, signal=0.4, times=1)
    assert torch.allclose(a.c1.weight, b.c1.weight, atol=1e-6)
    # C3 learns through BidirectionalSOM.fit, which picks the closed form (neighbourhood below the
    # cutoff, one pair repeated); it equals the SOM block's step-by-step online rule
    from neuroimagery.nn import som as som_module

    c, d = ToolUseBrain((6, 8), c3_eta=0.2), ToolUseBrain((6, 8), c3_eta=0.2)
    d.c3.som.weight.copy_(c.c3.som.weight)
    c.train(), d.train()
    chosen, choose = [], som_module.choose

    def spy(*a, **k):
        chosen.append(choose(*a, **k).name)
        return choose(*a, **k)

    monkeypatch.setattr("neuroimagery.nn.som.choose", spy)
    d.train_c3(x, unit=3, posture=2, outcome=out, times=9, generator=g)
    d.train_c3(x, unit=3, posture=2, outcome=out, times=9, generator=g)
    monkeypatch.undo()
    assert chosen == ["repeated", "repeated"]
    A, B = c.flat(out).unsqueeze(0), c._c3_b(x, 3).unsqueeze(0)
    for _ in range(2):
        c.c3.fit(A, B, labels=torch.tensor([[13]]), iterations=9, order=torch.zeros(1, 9, dtype=torch.long),
                 method="online")
    # float32 rounding of 18 steps: about one ulp of each weight (the code part is about 100)
    assert torch.allclose(c.c3.som.weight, d.c3.som.weight, rtol=1e-6, atol=1e-6)
    assert int(c.c3.som.steps) == int(d.c3.som.steps) == 18
    assert not torch.equal(c.c3.som.weight, ToolUseBrain((6, 8), c3_eta=0.2).c3.som.weight)


def test_brain_learns_through_its_connections_as_the_equations_say():
    """C1/C2 (eq. 4.2, gated outstar) and C4 (eq. 7.1) learn through ``Connection.learn``, with the
    numbers of the equations written out step by step; C3's read-out equals the SOM block's."""
    from neuroimagery.nn.connections import Connection

    g = torch.Generator().manual_seed(1)
    x = (torch.rand(2, 6, 8, generator=g) < 0.3).float()
    x1 = (torch.rand(2, 6, 8, generator=g) < 0.3).float()
    calls = []
    real_learn = Connection.learn

    def counting(self, *a, **kw):
        calls.append(self.name)
        return real_learn(self, *a, **kw)

    Connection.learn = counting
    try:
        # C1: five outstar steps w += eta x (y - w) on the trained row only
        b = ToolUseBrain((6, 8), c1_eta=0.2)
        b.c1.weight.uniform_(0, 1, generator=g)
        w0 = b.c1.weight[0].clone()
        b.train_c1(x, unit=4, signal=0.3, times=5)
        hand = w0.clone()
        xf = x.reshape(-1)
        for _ in range(5):
            hand[4] += 0.2 * xf * (0.3 - hand[4])
        assert torch.allclose(b.c1.weight[0], hand, atol=1e-6)
        b.train_c2(x, goal=1, times=3)
        # C4: eq. 7.1, with and without bootstrap
        for done in (False, True):
            q = ToolUseBrain((6, 8), q_eta=0.05)
            q.c4.weight.uniform_(-0.1, 0.1, generator=g)
            w = q.c4.weight[0].clone()
            q.train()
            q.q_update(x, unit=3, reward=1.0, x1=x1, done=done)
            q_max = 0.0 if done else float((w @ x1.reshape(-1)).max())
            w[3] += 0.05 * (1.0 + 0.8 * q_max - float(w[3] @ xf)) * xf
            assert torch.allclose(q.c4.weight[0], w, atol=1e-7)
    finally:
        Connection.learn = real_learn
    assert calls.count("C1") == 1 and calls.count("C2") == 1 and calls.count("C4") == 2
    # C3: the mental image equals the SOM block's own backward pass
    c = ToolUseBrain((6, 8), c3_eta=0.5)
    c.train()
    c.practise_in(3, x)
    c.train_c3(x, unit=2, posture=3, outcome=x1, times=20, generator=g)
    via_som = c.c3.backward(c._c3_b(x, 2)).reshape(2, 6, 8).clamp(0, 1)
    assert torch.allclose(c.imagine(x, 2), via_som, atol=1e-6)


def test_eye_reads_a_toy_on_either_side_of_the_reachable_border():
    """The reward read from an image agrees with the toy's true place 0.5 mm either side of the
    border (without taking off the reader's bias, about 1.4 mm, a toy 0.5 mm inside reads as out of
    reach, as a retrieving pull that stops just after the border often leaves it)."""
    from neuroimagery.models.tool_use import State, ToolWorldEnvironment

    env = ToolWorldEnvironment()
    assert 0.0005 < env.reader_bias() < 0.003
    for y in (-0.15, -0.10, -0.05):
        bx = env.world.cfg.reach_frontier_at(y)
        for p in (1, 4):
            inside, outside = env.perceive(State(p, None, (bx - 0.0005, y))), env.perceive(State(p, None, (bx + 0.0005, y)))
            assert env.reward(inside) == 1.0 and env.reward(outside) == 0.0, (y, p)
            assert abs(env.reader.toy_x(inside[0]) - env.reader_bias() - (bx - 0.0005)) < 0.0004


def test_a_scene_between_moves_keeps_the_toy_turn():
    """The scene after a move holds the toy's turn, the next move starts from it and the eye sees it."""
    from neuroimagery.models.tool_use import State, ToolWorldEnvironment

    env = ToolWorldEnvironment()
    q4 = env.world.initial_posture(4)
    still = env.dmp.pack(q4[None], torch.zeros(1, 7, env.dmp.n_basis))  # the arm stays where it is
    turned = State(4, tuple(q4.tolist()), (0.57, 0.01), 0.4)
    after = env.execute(still, turned, None)[0].next_state
    assert after.toy_xy == pytest.approx((0.57, 0.01), abs=0.002)
    assert after.toy_yaw == pytest.approx(0.4, abs=0.005)
    square = State(4, tuple(q4.tolist()), (0.57, 0.01))
    assert int((env.perceive(after)[0] != env.perceive(square)[0]).sum()) > 20


