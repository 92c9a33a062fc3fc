"""The reference rake drive: a fixed pybullet constraint drags the dynamic rake to every pose.

Every control step is simulated (slower than the kinematic drive of :mod:`neuroimagery.robot.world`);
kept to test the fast drive against (docs/robot.md).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch

from neuroimagery.robot import rake_plan
from neuroimagery.robot.events import EVENTS, Outcome, latch_events, toy_events, watched_indices, toy_fate


def simulate_constraint(world, poses: np.ndarray, posture: int, q0: torch.Tensor, watched) -> Outcome:
    """Every control step simulated, the rake dragged to its pose by a constraint."""
    cfg, c = world.cfg, world.client
    world.reset(posture)
    start, start_yaw = np.array(world.toy_xy()), world.toy_yaw()
    top = cfg.table_top + cfg.toy_size
    fired = [False] * 6
    first: str | None = None
    blew_up = False
    watched_i = watched_indices(watched)
    step = 0
    targets_pos, targets_orn = world._rake_targets(poses)
    targets_pos, targets_orn = targets_pos.tolist(), targets_orn.tolist()
    # the fastest any point of the target poses has moved up to each step (blow-up rule, toy_fate)
    pts = poses[:, None, :3, 3] + world._rake_points_np[:, :3] @ np.swapaxes(poses[:, :3, :3], -1, -2)
    rake_speed = rake_plan.fastest_so_far(rake_plan.sweep_of(pts), cfg)
    rest_z = cfg.table_top + cfg.toy_size / 2
    off_table = False
    for step in range(len(poses)):
        world._set_rake(poses[step], teleport=False, target=(targets_pos[step], targets_orn[step]))
        for _ in range(world.substeps):
            c.stepSimulation()
        pos, _ = c.getBasePositionAndOrientation(world.toy)
        vel, _ = c.getBaseVelocity(world.toy)
        fate = toy_fate(pos, vel, rake_speed[step], cfg)
        if fate == "blew_up":
            blew_up = True
            break
        now = toy_events(pos[0], pos[1], pos[0] - start[0], pos[1] - start[1], cfg, height=pos[2] - rest_z)
        first = latch_events(now, fired, first, top, cfg, lambda: c.getContactPoints(world.rake, world.toy))
        if fate == "off_table":
            off_table = True
            break
        if any(fired[i] for i in watched_i):
            break
    final = world.toy_xy()
    if blew_up:
        return Outcome((False,) * 6, None, (0.0, 0.0), step, tuple(float(v) for v in start), True,
                       final_toy_yaw=start_yaw)
    disp = (final[0] - float(start[0]), final[1] - float(start[1]))
    return Outcome(tuple(fired), first, disp, step, final, False, final_toy_yaw=world.toy_yaw(), off_table=off_table)


def rollout_constraint(world, traj: torch.Tensor, plan: dict, posture: int, watched, use_filter: bool,
                       t0: float) -> list[Outcome]:
    """The rollouts of ``world`` (a ``ToolWorld`` on this drive) of ``traj`` (N, T, 7) from ``posture``;
    ``plan``: its ``_plan`` of them; ``t0``: when the call began (the tensor time)."""
    N, T = traj.shape[:2]
    arm = plan["arm_step"]
    if world._table_collides:  # to the commanded poses, the table stopping the rake (table_contact="lift")
        with torch.no_grad():
            poses_t = world.kin.rake_pose(traj)
            near = world.near_toy(traj, poses=poses_t) if use_filter else torch.ones(N, dtype=torch.bool)
        near, poses = near.numpy(), poses_t.double().numpy()
    else:  # to the poses the table rule lets the rake take (``_plan``)
        near = (world._gaps(plan["pts"], world.cfg.toy_xy, plan["sweep"]).min(axis=-1) < world.cfg.filter_margin
                if use_filter else np.ones(N, dtype=bool))
        poses = plan["poses"]
    world.timing["tensor_s"] += time.perf_counter() - t0
    outcomes = []
    for n in range(N):
        if not bool(near[n]):
            outcomes.append(dataclasses.replace(world._skipped(T), arm_step=int(arm[n, T - 1])))
            continue
        t1 = time.perf_counter()
        out = simulate_constraint(world, poses[n], posture, traj[n, 0], watched)
        outcomes.append(dataclasses.replace(out, arm_step=int(arm[n, out.stop_step])))
        world.timing["physics_s"] += time.perf_counter() - t1
    return outcomes
