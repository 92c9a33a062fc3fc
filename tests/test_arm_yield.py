"""The table rule ``yield`` (robot.arm_yield): an arm of equal joint springs yields to the table."""
import numpy as np
import pytest
import torch
from scipy.optimize import minimize

from neuroimagery.robot import arm_yield, rake_plan
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.movements import MovementConfig, goal_noise, random_primitives, trajectories, world_dmp
from neuroimagery.robot.world import ToolWorld


@pytest.fixture(scope="module")
def yielding():
    with ToolWorld(WorldConfig(table_contact="yield")) as w:
        yield w


def _sinking_steps(world, n=12, seed=3):
    """Joint vectors (M, 7) of exploration movements from posture 1 whose rake would sink into the
    table, and how deep (M,)."""
    dmp, gen = world_dmp(), torch.Generator().manual_seed(seed)
    theta = goal_noise(world, dmp, random_primitives(world, dmp, n, MovementConfig(), gen), gen)
    q = trajectories(world, dmp, theta, world.initial_posture(1), MovementConfig()).double().numpy().reshape(-1, 7)
    geo, cfg = world._geometry, world.cfg
    _, below = rake_plan.below_floor(world.kin.rake_pose_np(q), geo.points, geo.point_radius, cfg.table_top + cfg.table_clearance)
    deep = below.max(axis=-1)
    return q[deep > 0], deep[deep > 0]


def test_the_yield_rests_the_rake_on_the_table_within_the_limits(yielding):
    w, geo = yielding, yielding._geometry
    floor = w.cfg.table_top + w.cfg.table_clearance
    q, deep = _sinking_steps(w)
    assert len(q) > 100 and deep.max() > 0.1  # some steps sink by more than 10 cm
    qy, ok, poses = arm_yield.yield_joints(w.kin, q, geo.points, geo.point_radius, w.cfg)
    lim = w.kin.joint_limits.double().numpy()
    assert ok.all()
    assert ((qy >= lim[:, 0] - 1e-12) & (qy <= lim[:, 1] + 1e-12)).all()
    _, below = rake_plan.below_floor(w.kin.rake_pose_np(qy), geo.points, geo.point_radius, floor)
    assert below.max() <= arm_yield.YIELD_TOLERANCE
    assert np.allclose(poses, w.kin.rake_pose_np(qy))  # the rake rigid in the hand
    # a command that does not sink is left alone
    q_free = w.initial_posture(3).double().numpy()[None]
    q_free[0, 0] -= 0.3  # the arm raised
    assert np.array_equal(arm_yield.yield_joints(w.kin, q_free, geo.points, geo.point_radius, w.cfg)[0], q_free)


def test_the_yield_is_close_to_the_least_joint_change(yielding):
    """Against a general optimiser (SLSQP: least squared joint change with every rake point at or
    above the table, within the limits) on sinking steps 0.5-21 cm deep."""
    w, geo = yielding, yielding._geometry
    floor = w.cfg.table_top + w.cfg.table_clearance
    q, deep = _sinking_steps(w)
    pick = np.argsort(deep)[np.linspace(len(deep) // 10, len(deep) - 1, 8).astype(int)]
    qy = arm_yield.yield_joints(w.kin, q[pick], geo.points, geo.point_radius, w.cfg)[0]
    lim = w.kin.joint_limits.double().numpy()
    ratios = []
    for i, m in enumerate(pick):
        q0 = q[m]

        def above(x):
            return -rake_plan.below_floor(w.kin.rake_pose_np(x[None]), geo.points, geo.point_radius, floor)[1][0]

        best = minimize(lambda x: ((x - q0) ** 2).sum(), qy[i], method="SLSQP", bounds=lim,
                        constraints=[{"type": "ineq", "fun": above}], options={"maxiter": 300, "ftol": 1e-12})
        assert best.success and above(best.x).min() > -1e-6
        ratios.append(np.linalg.norm(qy[i] - q0) / np.linalg.norm(best.x - q0))
    assert min(ratios) > 0.99  # never below the optimum (it would not rest on the table)
    assert np.median(ratios) < 1.02 and max(ratios) < 1.10


def test_the_arm_is_held_from_the_first_step_it_cannot_yield():
    ok = np.array([[True, True, False, True, True],
                   [True, True, True, True, True],
                   [False, True, True, True, True]])
    assert rake_plan.held_steps(ok).tolist() == [[0, 1, 1, 1, 1], [0, 1, 2, 3, 4], [0, 1, 2, 3, 4]]


def test_under_the_yield_the_plan_rests_the_rake_on_the_table_and_keeps_it_in_the_hand(yielding):
    w = yielding
    q0 = w.initial_posture(1)
    down = q0.clone()
    down[0] += 0.4  # shoulder pitch: swing the arm down, the head would sink into the table
    traj = (q0 + torch.linspace(0, 1, 30)[:, None] * (down - q0))[None].numpy()
    plan = w._plan(traj)
    low = (plan["pts"][..., 2] - w._point_radius).min(-1)
    assert low.min() >= w.cfg.table_top + w.cfg.table_clearance - arm_yield.YIELD_TOLERANCE - 1e-9
    assert (plan["arm_step"] == np.arange(30)).all()  # the arm yields at every step: never held
    cmd = w.kin.rake_pose_np(traj)
    moved = np.abs(plan["poses"] - cmd).max(axis=(-1, -2))[0]
    assert moved[0] < 1e-9 and moved[-1] > 0.05  # the posture rests on the table; the swing is yielded


def test_the_yielding_arm_is_never_stopped_and_yields_the_pressing_pulls(yielding):
    """Under ``table_contact="yield"``: pulls from posture 1, level, to the side, and pressing the
    head 4 and 8 cm into the table (the arm yields)."""
    from test_robot_world import _line

    pulls = ((-0.16, 0.0, 0.0), (-0.12, 0.05, 0.0), (-0.16, 0.0, -0.04), (-0.16, 0.0, -0.08))
    for delta in pulls:
        traj = _line(yielding, 1, delta)
        plan = yielding._plan(traj.numpy())
        assert (plan["arm_step"] == np.arange(traj.shape[1])).all()  # never stopped
        yielded = np.abs(plan["poses"] - yielding.kin.rake_pose_np(traj.numpy())).max()
        assert yielded > 0.01 or delta[2] == 0, delta  # the pressing pulls are yielded
