"""The kinematic drive's plan of a batch of rake trajectories, in numpy (no physics).

:func:`plan` turns the grip poses of a batch of trajectories into what pybullet needs at every
control step: the rake's lifted poses (the table stops it), its world points, the inertial-frame
positions and quaternions, the velocities that carry it from step ``t-1`` to ``t``, how far its
farthest point travels in each step (``sweep``) and how many physics steps that step needs
(``nsub``, docs/robot.md, physics step criterion). :func:`gaps` is the rake's distance to the
toy's box at every step, used to skip steps in which the rake cannot reach a resting toy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.rake_pose import quat_from_matrix, rotvec_between

GRAVITY = 9.81


@dataclass(frozen=True)
class RakeGeometry:
    """The rake as the plan sees it: sample points in the grip frame (P, 3), each point's radius
    (P,), the largest radius, and the grip -> inertial-frame rotation and offset."""

    points: np.ndarray
    point_radius: np.ndarray
    point_radius_max: float
    R_com: np.ndarray
    com: np.ndarray


def sweep_of(pts: np.ndarray) -> np.ndarray:
    """``pts`` (..., T, P, 3) rake points -> (..., T): the farthest any point travels from step
    ``t-1`` to ``t`` (0 at ``t = 0``)."""
    sweep = np.zeros(pts.shape[:-2])
    if pts.shape[-3] > 1:
        sweep[..., 1:] = np.linalg.norm(pts[..., 1:, :, :] - pts[..., :-1, :, :], axis=-1).max(axis=-1)
    return sweep


def fastest_so_far(sweep: np.ndarray, cfg: WorldConfig) -> list[float]:
    """The fastest any rake point has moved (m/s) up to each control step of one trajectory's
    ``sweep`` (T,): the speed a blow-up is measured against (``robot.events.toy_fate``)."""
    return (np.maximum.accumulate(sweep) / cfg.control_dt).tolist()


def substeps_for(sweep: np.ndarray, cfg: WorldConfig, substeps: int) -> np.ndarray:
    """Physics steps per control step: at least ``substeps`` (``control_dt / physics_dt``), and
    enough that no rake point moves farther than ``cfg.max_substep_travel`` in one of them."""
    n = np.full(sweep.shape, substeps, dtype=np.int64)
    if cfg.max_substep_travel is not None:
        n = np.maximum(n, np.ceil(sweep / float(cfg.max_substep_travel) - 1e-9).astype(np.int64))
    return n


def plan(poses: np.ndarray, geo: RakeGeometry, cfg: WorldConfig, substeps: int) -> dict:
    """``poses`` (N, T, 4, 4) grip poses -> the plan's arrays (module doc), batch axes kept.

    A pose whose lowest rake point would sink below ``table_top + table_clearance`` is raised
    vertically.  The velocities include the gravity the physics steps take off, so that the rake
    lands exactly on pose ``t``: ``n`` semi-implicit Euler steps of ``h = dt / n`` lose
    ``g h dt (n + 1) / 2`` of height.
    """
    pts = poses[..., None, :3, 3] + geo.points @ np.swapaxes(poses[..., :3, :3], -1, -2)  # (N, T, P, 3)
    low = (pts[..., 2] - geo.point_radius).min(axis=-1)  # (N, T)
    lift = np.maximum(cfg.table_top + cfg.table_clearance - low, 0.0)
    poses = poses.copy()
    poses[..., 2, 3] += lift
    pts[..., 2] += lift[..., None]
    R = poses[..., :3, :3] @ geo.R_com
    pos = poses[..., :3, 3] + poses[..., :3, :3] @ geo.com
    quat = quat_from_matrix(R)
    dt = cfg.control_dt
    lin = np.zeros_like(pos)
    ang = np.zeros_like(pos)
    if pos.shape[1] > 1:
        lin[:, 1:] = (pos[:, 1:] - pos[:, :-1]) / dt
        ang[:, 1:] = rotvec_between(quat[:, :-1], quat[:, 1:]) / dt
    sweep = sweep_of(pts)
    nsub = substeps_for(sweep, cfg, substeps)
    lin[:, 1:, 2] += GRAVITY * dt * (nsub[:, 1:] + 1) / (2 * nsub[:, 1:])
    return {"poses": poses, "pts": pts, "pos": pos, "orn": quat, "lin": lin, "ang": ang, "sweep": sweep,
            "nsub": nsub}


def gaps(pts: np.ndarray, toy_xy, sweep: np.ndarray, cfg: WorldConfig, point_radius_max: float) -> np.ndarray:
    """Per control step, the smallest distance between the rake and the toy's box while moving.

    ``pts`` (..., T, P, 3), ``sweep`` (..., T) -> (..., T).  The toy is taken as the square
    around its circumscribed circle (so any yaw is covered); step ``t`` moves the rake from
    pose ``t-1`` to ``t``, so its distance is the smaller of the two ends minus half the
    farthest any rake point travels in the step.
    """
    h = cfg.toy_size / 2 * math.sqrt(2.0)
    lo = np.array([toy_xy[0] - h, toy_xy[1] - h, cfg.table_top])
    hi = np.array([toy_xy[0] + h, toy_xy[1] + h, cfg.table_top + cfg.toy_size])
    d = np.maximum(np.maximum(lo - pts, pts - hi), 0.0)
    g = np.sqrt((d * d).sum(axis=-1).min(axis=-1)) - point_radius_max  # (..., T)
    out = g.copy()
    out[..., 1:] = np.minimum(g[..., 1:], g[..., :-1]) - 0.5 * sweep[..., 1:]
    return out
