"""The tool-use world's physics step and the toy thrown off the table (docs/robot.md)."""
import numpy as np
import pytest
import torch

from neuroimagery.robot.config import OFF_TABLE_XY, WorldConfig
from neuroimagery.robot.events import toy_fate
from neuroimagery.robot.movements import MovementConfig, goal_noise, random_primitives, trajectories, world_dmp
from neuroimagery.robot.world import ToolWorld
from test_robot_world import _line


@pytest.fixture(scope="module")
def world():
    with ToolWorld() as w:
        yield w


def _random_trajectories(world, posture, n, seed):
    dmp, gen = world_dmp(), torch.Generator().manual_seed(seed)
    theta = goal_noise(world, dmp, random_primitives(world, dmp, n, MovementConfig(), gen), gen)
    return trajectories(world, dmp, theta, world.initial_posture(posture), MovementConfig())


def test_no_rake_point_travels_farther_than_the_bound_in_one_physics_step(world):
    plan = world._plan(_random_trajectories(world, 1, 40, 3).numpy())
    travel = world.cfg.max_substep_travel
    assert travel == pytest.approx(0.008)
    assert (plan["nsub"] >= world.substeps).all()
    assert (plan["sweep"] / plan["nsub"] <= travel + 1e-12).all()
    assert (plan["nsub"] > world.substeps).any()  # random movements do need the finer steps
    # one step fewer would break the bound wherever more than two are used
    more = plan["nsub"] > world.substeps
    assert (plan["sweep"][more] / (plan["nsub"][more] - 1) > travel).all()
    with ToolWorld(WorldConfig(max_substep_travel=None)) as fixed:
        plan = fixed._plan(_random_trajectories(fixed, 1, 10, 3).numpy())
        assert (plan["nsub"] == fixed.substeps).all()


@pytest.mark.parametrize("n", [2, 3, 7, 20])
def test_a_lone_rake_lands_on_its_next_pose_with_any_number_of_physics_steps(world, n):
    """The velocities make up for the gravity of n semi-implicit Euler steps of control_dt / n."""
    p, cid, cfg = world.p, world._cid, world.cfg
    q0 = world.initial_posture(3)
    q1 = q0.clone()
    q1[0] -= 0.3  # lift the arm: the rake moves in the air, nothing to hit
    plan = world._plan(torch.stack([q0, q1]).numpy()[None])
    sweep = plan["sweep"][0, 1]
    fixed = dict(plan)
    fixed["nsub"] = np.full_like(plan["nsub"], n)
    lin = plan["lin"].copy()
    lin[0, 1, 2] += 9.81 * cfg.control_dt * ((n + 1) / (2 * n) - (plan["nsub"][0, 1] + 1) / (2 * plan["nsub"][0, 1]))
    world.reset(3)
    p.changeDynamics(world.rake, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)  # gravity alone
    p.resetBasePositionAndOrientation(world.rake, plan["pos"][0, 0].tolist(), plan["orn"][0, 0].tolist(), physicsClientId=cid)
    p.resetBaseVelocity(world.rake, lin[0, 1].tolist(), plan["ang"][0, 1].tolist(), physicsClientId=cid)
    world._set_physics_step(n)
    try:
        for _ in range(n):
            p.stepSimulation(physicsClientId=cid)
    finally:
        world._set_physics_step(world.substeps)
        p.changeDynamics(world.rake, -1, linearDamping=0.04, angularDamping=0.04, physicsClientId=cid)
    landed = np.array(p.getBasePositionAndOrientation(world.rake, physicsClientId=cid)[0])
    assert sweep > 0.01
    assert np.abs(landed - plan["pos"][0, 1]).max() < 1e-6


def test_fast_control_steps_take_more_physics_steps_in_the_simulation(world):
    traj = _line(world, 1, (-0.16, 0.0, 0.0), T=6)
    counts = {}
    for travel in (0.008, None):
        with ToolWorld(WorldConfig(max_substep_travel=travel)) as w:
            w.rollout(traj, 1, None)
            counts[travel] = (w.steps_simulated, w.physics_steps)
    assert counts[None][1] == 2 * counts[None][0]
    assert counts[0.008][1] > 2 * counts[0.008][0]


def test_a_fast_pull_throws_the_toy_off_the_table_and_its_events_stand(world):
    fast = _line(world, 1, (-0.16, 0.0, 0.0), T=3)
    traj = torch.cat([fast, fast[:, -1:].repeat(1, 60, 1)], 1)  # then the arm holds still
    out = world.rollout(traj, 1, None)[0]
    assert out.off_table and not out.blew_up
    assert out.fired("south") and out.fired("retrieve")  # it crossed the reachable area on the table
    assert out.stop_step < traj.shape[1] - 1  # the rollout stopped when it fell
    assert out.toy_displacement[0] < -0.4  # past the table's near edge (x = 0.15 m)


def test_a_thrown_toy_is_out_of_play_in_later_scenes(monkeypatch):
    import dataclasses

    from neuroimagery.models.tool_use import ToolWorldEnvironment

    env = ToolWorldEnvironment()
    try:
        real = env.world.rollout

        def thrown(traj, posture, watched=None, use_filter=True):
            return [dataclasses.replace(o, off_table=True) for o in real(traj, posture, watched, use_filter=use_filter)]

        gen = torch.Generator().manual_seed(0)
        monkeypatch.setattr(env.world, "rollout", thrown)
        res = env.execute(env.random_primitive(gen)[None], env.start(1), None)[0]
        monkeypatch.undo()
        assert res.off_table and res.next_state.toy_xy == OFF_TABLE_XY
        assert float(env.perceive(res.next_state)[0].sum()) == 0.0  # the eye no longer sees it
        params = torch.stack([env.random_primitive(gen) for _ in range(20)])
        again = env.execute(params, res.next_state, None)
        assert not any(any(r.events) for r in again)  # nothing the rake does brings it back
    finally:
        env.close()


def test_toy_fate_separates_throws_from_blow_ups():
    cfg = WorldConfig()
    on = (0.5, 0.0, cfg.table_top + cfg.toy_size / 2)
    assert toy_fate(on, (0.0, 0.0, 0.0), 0.0, cfg) == "on_table"
    assert toy_fate(on, (8.9, 0.0, 0.0), 4.0, cfg) == "on_table"  # 2 x 4 m/s + 1 m/s allows 9
    assert toy_fate(on, (9.1, 0.0, 0.0), 4.0, cfg) == "blew_up"
    assert toy_fate(on, (float("nan"), 0.0, 0.0), 4.0, cfg) == "blew_up"
    assert toy_fate((0.1, 0.0, cfg.table_top - 0.01), (1.0, 0.0, -1.0), 2.0, cfg) == "off_table"
    with pytest.raises(ValueError, match="max_substep_travel"):
        WorldConfig(max_substep_travel=0.0)
    with pytest.raises(ValueError, match="blowup_speed_factor"):
        WorldConfig(blowup_speed_factor=-1.0)
