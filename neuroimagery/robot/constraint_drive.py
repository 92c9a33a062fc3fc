"""The reference rake drive: a fixed pybullet constraint drags the dynamic rake to every pose.

Every control step is simulated (slower than the kinematic drive of :mod:`neuroimagery.robot.world`);
kept to test the fast drive against (docs/robot.md).
"""
from __future__ import annotations

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
