"""Experiment 5 contracts W9-W11 (docs/contracts.md): exploration as Fig. 7.5 writes it (the goal
reinitialised to the chosen initial posture before the noise), the arm stopped at the first new
event, and each robot's library acquired with its own detectors."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from support_tool_env import StandInToolEnv  # noqa: E402

from neuroimagery.models.tool_use import EVENTS, AcquisitionParams, acquire_skills  # noqa: E402


@pytest.fixture(scope="module")
def world():
    from neuroimagery.robot.world import ToolWorld

    w = ToolWorld()
    yield w
    w.close()


def test_w9_exploration_goals_are_the_chosen_posture_plus_noise(world):
    from neuroimagery.robot.movements import MovementConfig, explore, random_primitives, world_dmp

    dmp = world_dmp()
    g = torch.Generator().manual_seed(0)
    theta = random_primitives(world, dmp, 400, MovementConfig(), g)
    q0 = world.initial_posture(3)
    goals, w = dmp.split(explore(world, dmp, theta, q0, g))
    lim = world.kin.joint_limits.float()
    sigma = world.cfg.goal_noise_share * (lim[:, 1] - lim[:, 0])
    # centred on the posture (not on the DMPs' random goals), spread by the goal noise rule
    assert ((goals.mean(0) - q0).abs() < 0.25 * sigma).all()
    assert ((goals.std(0) - sigma).abs() < 0.25 * sigma).all()
    assert torch.equal(w, dmp.split(theta)[1])  # shape weights untouched


def test_w10_a_watched_rollout_stops_at_the_first_firing_of_any_watched_event(world):
    from neuroimagery.robot.movements import MovementConfig, explore, random_primitives, trajectories, world_dmp

    dmp, cfg = world_dmp(), MovementConfig()
    g = torch.Generator().manual_seed(1)
    q0 = world.initial_posture(1)
    traj = trajectories(world, dmp, explore(world, dmp, random_primitives(world, dmp, 60, cfg, g), q0, g), q0, cfg)
    free = world.rollout(traj, 1, watched=None)
    south = world.rollout(traj, 1, watched="south")
    both = world.rollout(traj, 1, watched=("north", "south"))
    checked = 0
    for f, s, b in zip(free, south, both):
        if f.events[EVENTS.index("south")] and not f.events[EVENTS.index("north")]:
            checked += 1
            assert s.events[EVENTS.index("south")] and s.stop_step <= f.stop_step
            assert b.stop_step == s.stop_step  # north never fired: the pair stops where south does
    assert checked >= 3


def test_w10_exploration_watches_the_enabled_detectors_not_yet_acquired():
    class Spy(StandInToolEnv):
        calls: list = []

        def execute(self, params, state, watched):
            if watched is None or not isinstance(watched, str):
                Spy.calls.append(watched)
            return super().execute(params, state, watched)

    env = Spy()
    enabled = ["retrieve", "touch", "west"]
    acq = AcquisitionParams(max_epochs=2, explore_max_rollouts=200, c1_repeats=1, c2_repeats=1, c3_repeats=1)
    lib = acquire_skills(env, enabled, acq, torch.Generator().manual_seed(2))
    explored = [c for c in Spy.calls if c is not None]
    assert explored and all(set(c) <= set(enabled) for c in explored)
    # once a skill is acquired its detector is no longer watched in later exploration
    first = lib.skills[0].event
    after = explored[[i for i, c in enumerate(explored) if first in c][-1] + 1:]
    assert all(first not in c for c in after)


def test_w11_each_robot_library_is_acquired_with_its_own_detectors(tmp_path, monkeypatch):
    from neuroimagery.experiments.exp5 import protocol as exp5, config as exp5_config

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    e = exp5_config.Exp5Config(repetitions=1, hp1_levels=[2, 4], hp1_ages=[14, 18], hp2_trials=[0], hp2_ages=[14],
                               situations=["behind"],
                               world=exp5_config.WorldParams(environment="support_tool_env:StandInToolEnv"),
                               acquisition=AcquisitionParams(max_epochs=2, explore_max_rollouts=100, c1_repeats=1,
                                                             c2_repeats=1, c3_repeats=1))
    out = exp5.run_task(e, 0, dict(repetition=0, situations=["behind"], key="rep000_behind"))
    for row in out["rows"]:
        lib = out["libraries"][row["detectors"]]
        events = {s["event"] for s in lib["skills"]}
        assert events <= set(row["detectors"].split("+"))
        assert row["skills"] == "+".join(s["event"] for s in lib["skills"]) or row["n_skills"] == len(lib["skills"])
    assert len(out["libraries"]) == len({r["detectors"] for r in out["rows"]})
