"""The kinematic drive's plan of a batch of rake trajectories, in numpy (no physics).

:func:`plan` turns the grip poses of a batch of trajectories into what pybullet needs at every
control step: the rake's poses where the table lets it be (:func:`table_poses`), its world points, the inertial-frame
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


def _rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about unit ``axis`` (..., 3) by ``angle`` (...) (Rodrigues)."""
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    c, s = np.cos(angle), np.sin(angle)
    C = 1 - c
    return np.stack([
        np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
        np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
        np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1)], -2)


def grip_pivot(poses: np.ndarray, pts: np.ndarray, geo: RakeGeometry, cfg: WorldConfig,
               iters: int = 14) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The compliant grip (docs/robot.md, "The table, the grip and the arm", rule 1).

    ``poses`` (M, 4, 4) grip poses whose lowest rake point would sink below ``table_top +
    table_clearance``, ``pts`` (M, P, 3) their rake points -> the smallest turn ``phi`` (M,) in
    ``[0, grip_pivot_max]`` about the grip, about the horizontal axis across the handle, that rests
    the rake on the table; whether it exists (M,) bool; and the turn's rotations (M, 3, 3).  Each
    point's height is ``z_grip + A cos(phi) + B sin(phi)``, increasing in ``phi`` over the range
    (the handle points less than 90 degrees up), so the turn is found by bisection.
    """
    floor = cfg.table_top + cfg.table_clearance
    grip = poses[:, :3, 3]
    h = poses[:, :3, 0]  # the handle's direction
    a = np.stack([h[:, 1], -h[:, 0], np.zeros(len(h))], -1)  # h x z: the upward push's torque axis
    na = np.linalg.norm(a, axis=-1)
    a = a / np.maximum(na, 1e-12)[:, None]
    p = pts - grip[:, None, :]
    A = p[..., 2]
    B = a[:, None, 0] * p[..., 1] - a[:, None, 1] * p[..., 0]  # (a x p)_z
    zg = grip[:, None, 2] - geo.point_radius[None, :]

    def low(phi):
        return (zg + A * np.cos(phi)[:, None] + B * np.sin(phi)[:, None]).min(axis=-1) - floor

    top = np.full(len(poses), float(cfg.grip_pivot_max))
    ok = (low(top) >= -1e-9) & (na > 1e-9)
    lo, hi = np.zeros(len(poses)), top
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        up = low(mid) >= 0
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    phi = np.where(ok, hi, 0.0)
    return phi, ok, _rotation(a, phi)


def below_floor(poses: np.ndarray, points: np.ndarray, point_radius: np.ndarray, floor: float):
    """Grip poses (..., 4, 4) -> every rake point in the world (..., P, 3) and how far each point's
    bottom lies below ``floor`` (..., P; negative above it)."""
    pts = poses[..., None, :3, 3] + points @ np.swapaxes(poses[..., :3, :3], -1, -2)
    return pts, floor - (pts[..., 2] - point_radius)


def _rake_points(poses: np.ndarray, geo: RakeGeometry, cfg: WorldConfig) -> tuple[np.ndarray, np.ndarray]:
    """Grip poses (N, T, 4, 4) -> the rake's points (N, T, P, 3) and how far each pose's lowest
    point lies below ``table_top + table_clearance`` (N, T; 0 where it does not)."""
    pts, below = below_floor(poses, geo.points, geo.point_radius, cfg.table_top + cfg.table_clearance)
    return pts, np.maximum(below.max(axis=-1), 0.0)


def held_steps(ok: np.ndarray) -> np.ndarray:
    """``ok`` (N, T) whether the arm can rest the rake on the table at each step -> the step whose
    joints the arm holds (N, T): ``t`` up to the first step it cannot, the step before that one
    from there to the end (a start it cannot, never one of the four postures, is kept throughout)."""
    N, T = ok.shape
    steps = np.broadcast_to(np.arange(T), (N, T))
    first_bad = np.where(ok.all(axis=1), T, (~ok).argmax(axis=1))
    return np.where(first_bad[:, None] >= 1, np.minimum(steps, first_bad[:, None] - 1), steps)


def table_poses(poses: np.ndarray, geo: RakeGeometry, cfg: WorldConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``poses`` (N, T, 4, 4) commanded grip poses -> the poses the table lets the rake take, their
    rake points (N, T, P, 3) and the arm's step (N, T): the index of the trajectory point whose
    joints the arm holds (``t`` unless the table stopped it).

    ``table_contact = "lift"`` (default): every pose that would sink is lifted vertically.
    ``"yield"``: the poses come from the yielding arm's joints (:mod:`robot.arm_yield`) and rest
    on the table; what still lies below it (within the yield's tolerance) is lifted.
    ``"grip"``: the compliant grip (:func:`grip_pivot`); from the first step it cannot rest on the
    table the arm holds the step before for the rest of the movement; a start the grip cannot rest
    on the table keeps the vertical lift throughout.
    """
    pts, lift = _rake_points(poses, geo, cfg)
    N, T = lift.shape
    steps = np.broadcast_to(np.arange(T), (N, T))
    poses = poses.copy()
    if cfg.table_contact != "grip":  # lift; under "yield" (robot.arm_yield) only what stays below
        poses[..., 2, 3] += lift
        pts[..., 2] += lift[..., None]
        return poses, pts, steps.copy()
    sink = lift > 0
    ok = ~sink
    if sink.any():
        phi, turned, rot = grip_pivot(poses[sink], pts[sink], geo, cfg)
        grip = poses[sink][:, None, :3, 3]
        new_pts = grip + np.einsum("mij,mpj->mpi", rot, pts[sink] - grip)
        new_R = rot @ poses[sink][:, :3, :3]
        # a step the grip cannot rest on the table: lifted, used only before the first one it can
        lifted = lift[sink][:, None]
        new_pts = np.where(turned[:, None, None], new_pts, pts[sink] + np.array([0.0, 0.0, 1.0]) * lifted[..., None])
        P = poses[sink]
        P[:, :3, :3] = np.where(turned[:, None, None], new_R, P[:, :3, :3])
        P[:, 2, 3] += np.where(turned, 0.0, lift[sink])
        poses[sink], pts[sink] = P, new_pts
        ok[sink] = turned
    # the table stops the arm at its first step the grip cannot rest on the table, for the rest
    # of the movement; a start it cannot (never one of the four postures) keeps the lift throughout
    arm = held_steps(ok)
    if (arm != steps).any():
        poses = np.take_along_axis(poses, arm[..., None, None], axis=1)
        pts = np.take_along_axis(pts, arm[..., None, None], axis=1)
    return poses, pts, arm


def plan(poses: np.ndarray, geo: RakeGeometry, cfg: WorldConfig, substeps: int,
         arm_step: np.ndarray | None = None) -> dict:
    """``poses`` (N, T, 4, 4) grip poses -> the plan's arrays (module doc), batch axes kept.

    The table meets the rake by ``cfg.table_contact`` (:func:`table_poses`); ``arm_step`` (N, T)
    says which trajectory point's joints the arm holds at each step (given by the caller under
    ``"yield"``, whose arm the caller moves).  The velocities include the
    gravity the physics steps take off, so that the rake lands exactly on pose ``t``: ``n``
    semi-implicit Euler steps of ``h = dt / n`` lose ``g h dt (n + 1) / 2`` of height.
    """
    poses, pts, arm = table_poses(poses, geo, cfg)
    if arm_step is not None:
        arm = arm_step
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
            "nsub": nsub, "arm_step": arm}


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
