"""Stage 1's pull paths (docs/world_calibration.md, constraint 7), by forward kinematics only.

A skill keeps absolute joint goals (eq. 7.3), so a pull performed from posture 4 is a transit from
posture 4 to the pull's own goal. :func:`pull_paths` draws exploration movements from posture 1
(the W9 rule, ``robot.movements``), keeps those whose plate, raised where the table would sink the
rake (the lift), sweeps from behind the toy to the reachable area's edge within the toy's y-span
(*pull-like*), and rolls the same parameter vectors out from posture 4: the share whose path brings
a plate point beyond the toy's far face, within its y-span, below its top, is *pull paths behind*
(as ``benchmarks/exp5_pull_from_4.py`` measures it on learnt pulls).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import torch

from .config import WorldConfig

CHUNK = 250  # movements per forward-kinematics batch (memory)


def rake_points(cfg: WorldConfig) -> np.ndarray:
    """A coarse grid of the plate (both faces, 9 x 5) and 11 handle points, homogeneous (P, 4),
    in the rake frame; the first ``n_plate`` rows are the plate's."""
    hx, hy, hz = cfg.rake_head_offset
    c, s = math.cos(-0.4363323), math.sin(-0.4363323)  # the plate's pitch (urdf/rake.urdf)
    t, w, h = cfg.rake_plate
    plate = [(hx + c * dx + s * dz, hy + dy, hz - s * dx + c * dz, 1.0)
             for dx in (-t / 2, t / 2) for dy in np.linspace(-w / 2, w / 2, 9) for dz in np.linspace(-h / 2, h / 2, 5)]
    handle = [(x, 0.0, 0.0, 1.0) for x in np.linspace(0.0, cfg.rake_length, 11)]
    return np.array(plate + handle)


def _plate_paths(kin, cfg: WorldConfig, theta: torch.Tensor, q0: torch.Tensor, dmp, moves) -> np.ndarray:
    """Plate points (N, T, P, 3) of the DMPs ``theta`` from ``q0``, the rake raised where its lowest
    point (handle included) would sink below the table (the lift)."""
    traj = kin.clamp(dmp.rollout(theta.float(), q0, moves.duration_s, moves.dt))
    poses = kin.rake_pose_np(traj.double().numpy())
    pts = np.einsum("ntij,pj->ntpi", poses, rake_points(cfg))[..., :3]
    lift = np.maximum(0.0, cfg.table_top + cfg.table_clearance - pts[..., 2].min(axis=2, keepdims=True))
    pts[..., 2] += lift
    return pts[:, :, :90]


def _in_column(cfg: WorldConfig, pts: np.ndarray) -> np.ndarray:
    (tx, ty), h = cfg.toy_xy, cfg.toy_size / 2
    return (np.abs(pts[..., 1] - ty) < h) & (pts[..., 2] < cfg.table_top + cfg.toy_size)


def pull_paths(cfg: WorldConfig, weight_sigma: float, n: int, seed: int, duration_s: float = 1.5) -> dict:
    """``pull_like`` (share of ``n`` exploration movements from posture 1, stream ``seed``) and
    ``behind`` (share of the pull-like ones whose path from posture 4 passes behind the toy; None
    when there is none)."""
    from .kinematics import ArmKinematics
    from .movements import MovementConfig, explore, random_primitives, world_dmp

    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    world = SimpleNamespace(kin=kin, cfg=cfg)
    dmp, moves = world_dmp(), MovementConfig(weight_sigma=weight_sigma, duration_s=duration_s, dt=cfg.control_dt)
    gen = torch.Generator().manual_seed(seed)
    q1, q4 = (torch.tensor(cfg.postures[k], dtype=torch.float32) for k in (0, 3))
    far, edge = cfg.toy_xy[0] + cfg.toy_size / 2, cfg.reach_frontier_at(cfg.toy_xy[1]) + cfg.toy_size / 2
    pulls, behind = 0, 0
    for start in range(0, n, CHUNK):
        theta = explore(world, dmp, random_primitives(world, dmp, min(CHUNK, n - start), moves, gen), q1, gen)
        pts = _plate_paths(kin, cfg, theta, q1, dmp, moves)
        col = _in_column(cfg, pts)
        back = (col & (pts[..., 0] > far)).any(axis=2)  # (N, T)
        near = (col & (pts[..., 0] <= edge)).any(axis=2)
        T = back.shape[1]
        first_back = np.where(back.any(axis=1), back.argmax(axis=1), T)
        last_near = np.where(near.any(axis=1), T - 1 - near[:, ::-1].argmax(axis=1), -1)
        pull = first_back < last_near
        if pull.any():
            pts4 = _plate_paths(kin, cfg, theta[torch.from_numpy(pull)], q4, dmp, moves)
            behind += int((_in_column(cfg, pts4) & (pts4[..., 0] > far)).any(axis=(1, 2)).sum())
            pulls += int(pull.sum())
    return dict(pull_like=pulls / n, pulls=pulls, behind=behind / pulls if pulls else None, movements=n)
