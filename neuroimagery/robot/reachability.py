"""Where the arm can rest the rake's plate on the table, by forward kinematics only: the
reachability table of the calibration's posture sampling (docs/world_calibration.md, second
amendment).

:func:`base_table` draws ``TABLE_DRAWS`` joint vectors (seed ``TABLE_SEED``) uniformly inside the
posture fit's bounds (every joint ``MARGIN`` of its range from its limits) and moves each, by a
few Gauss-Newton steps on two constraints only, until the plate's width is horizontal and its
lowest point rests ``CLEARANCE`` above the table (the rake of the present world). :func:`reachable`
re-projects that table for a candidate's rake and keeps the joint vectors that converged with the
handle's heading inside the searched ranges: each row is a pose the arm reaches exactly (plate
centre, yaw, pitch, joint vector). :func:`place` maps a sampled plate-centre target and heading
onto the nearest row inside a region (posture 1's band, or a distance range from the toy).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from .config import WorldConfig

TABLE_SEED = 101  # the calibration's seeds start at 100 (docs/world_calibration.md)
TABLE_DRAWS = 60_000
MARGIN = 0.12  # the posture fit's bounds (robot.posture_fit)
CLEARANCE = 0.005  # the plate's lowest point above the table, as the posture fit puts it
YAW_RANGE, PITCH_RANGE = (-45.0, 60.0), (15.0, 40.0)  # the headings searched (degrees)
XY_UNIT, HEADING_UNIT = 0.01, 5.0  # place's metric: 1 cm of plate centre counts as 5 degrees of heading
CONVERGED = (1e-3, 5e-4)  # |plate width's vertical component|, |lowest point - its height| (m)


def _kin(cfg: WorldConfig):
    from .kinematics import ArmKinematics

    return ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                         rake_head_offset=tuple(cfg.rake_head_offset))


def _corners(cfg: WorldConfig) -> np.ndarray:
    """The plate box's eight corners (homogeneous, rake frame): its lowest point is one of them."""
    from .scene_check import PLATE_PITCH

    hx, hy, hz = cfg.rake_head_offset
    c, s = math.cos(PLATE_PITCH), math.sin(PLATE_PITCH)
    t, w, h = cfg.rake_plate
    return np.array([(hx + c * dx + s * dz, hy + dy, hz - s * dx + c * dz, 1.0)
                     for dx in (-t / 2, t / 2) for dy in (-w / 2, w / 2) for dz in (-h / 2, h / 2)])


def _residual(kin, corners: np.ndarray, height: float, q: np.ndarray, jacobian: bool = False):
    """The two constraints' residuals (N, 2) and, with ``jacobian``, their Jacobian (N, 2, 7)."""
    T, axis, point = kin.rake_frames_np(q, joints=jacobian)
    pts = np.einsum("nij,pj->npi", T[:, :3], corners)
    low = pts[..., 2].argmin(axis=1)
    r = np.stack([T[:, 2, 1], pts[np.arange(len(q)), low, 2] - height], axis=1)
    if not jacobian:
        return r
    p = pts[np.arange(len(q)), low][:, None, :]  # the lowest corner (N, 1, 3)
    J = np.stack([np.cross(axis, T[:, None, :3, 1])[..., 2], np.cross(axis, p - point)[..., 2]], axis=1)
    return r, J


def project(cfg: WorldConfig, q: np.ndarray, steps: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Joint vectors ``q`` (N, 7) moved by ``steps`` minimum-norm Gauss-Newton steps toward the
    plate resting on the table, width horizontal (kept inside the fit's bounds), and whether each
    converged."""
    kin = _kin(cfg)
    lim = kin.joint_limits.double().numpy()
    lo, hi = lim[:, 0] + MARGIN * (lim[:, 1] - lim[:, 0]), lim[:, 1] - MARGIN * (lim[:, 1] - lim[:, 0])
    corners, height = _corners(cfg), cfg.table_top + CLEARANCE
    q = np.clip(np.array(q, dtype=np.float64), lo, hi)
    for _ in range(steps):
        r, J = _residual(kin, corners, height, q, jacobian=True)
        JJt = J @ J.transpose(0, 2, 1) + 1e-9 * np.eye(2)
        dq = -(J.transpose(0, 2, 1) @ np.linalg.solve(JJt, r[..., None]))[..., 0]
        q = np.clip(q + dq, lo, hi)
    r = np.abs(_residual(kin, corners, height, q))
    return q, (r[:, 0] < CONVERGED[0]) & (r[:, 1] < CONVERGED[1])


@lru_cache(maxsize=2)
def base_table(draws: int = TABLE_DRAWS, seed: int = TABLE_SEED) -> np.ndarray:
    """The converged joint vectors of ``draws`` uniform draws (stream ``seed``), projected with the
    present world's rake; computed once per process."""
    cfg = WorldConfig()
    lim = _kin(cfg).joint_limits.double().numpy()
    lo, hi = lim[:, 0] + MARGIN * (lim[:, 1] - lim[:, 0]), lim[:, 1] - MARGIN * (lim[:, 1] - lim[:, 0])
    q = np.random.default_rng(seed).uniform(lo, hi, size=(draws, 7))
    q, ok = project(cfg, q)
    q = q[ok]
    q.setflags(write=False)
    return q


def poses(cfg: WorldConfig, q: np.ndarray) -> np.ndarray:
    """(N, 4): plate centre x, y and the handle's yaw and pitch (degrees) of joint vectors ``q``."""
    T = _kin(cfg).rake_pose_np(q)
    c = T @ np.array([*cfg.rake_head_offset, 1.0])
    h = T[:, :3, 0]
    return np.stack([c[:, 0], c[:, 1], np.degrees(np.arctan2(h[:, 1], h[:, 0])),
                     np.degrees(np.arcsin(np.clip(-h[:, 2], -1.0, 1.0)))], axis=1)


def reachable(cfg: WorldConfig, draws: int = TABLE_DRAWS, seed: int = TABLE_SEED) -> tuple[np.ndarray, np.ndarray]:
    """The reachability table for ``cfg``'s rake: joint vectors (M, 7) and their :func:`poses`, the
    base table re-projected with this rake, converged and headed inside the searched ranges."""
    q, ok = project(cfg, base_table(draws, seed), steps=6)
    q = q[ok]
    x = poses(cfg, q)
    keep = ((x[:, 2] >= YAW_RANGE[0]) & (x[:, 2] <= YAW_RANGE[1])
            & (x[:, 3] >= PITCH_RANGE[0]) & (x[:, 3] <= PITCH_RANGE[1]))
    return q[keep], x[keep]


def nearest(x: np.ndarray, vals, region: np.ndarray) -> tuple[int, float] | None:
    """The row of ``x`` (M, 4: two lengths, two angles) nearest to ``vals`` among those where
    ``region`` (M,) is true, in the metric 1 cm = 5 degrees, and its distance in those units; None
    when the region holds no row."""
    region = np.asarray(region, dtype=bool)
    if len(region) != len(x):
        raise ValueError(f"place: region has {len(region)} rows, the table {len(x)}")
    if not region.any():
        return None
    vals = np.asarray(vals, dtype=np.float64)
    if not np.isfinite(vals).all():
        raise ValueError(f"place: target and heading must be finite numbers, got {vals.tolist()}")
    d = np.sqrt(((x[:, :2] - vals[:2]) ** 2).sum(axis=1) / XY_UNIT ** 2
                + ((x[:, 2:] - vals[2:]) ** 2).sum(axis=1) / HEADING_UNIT ** 2)
    d = np.where(region, d, np.inf)
    i = int(np.argmin(d))
    return i, float(d[i])


def place(table: tuple[np.ndarray, np.ndarray], target_xy, yaw: float, pitch: float, region: np.ndarray):
    """The sampled plate-centre ``target_xy`` and heading (``yaw``, ``pitch``, degrees) mapped into
    the reachable set: the nearest row of ``table`` among those where ``region`` (M,) is true, in
    the metric 1 cm = 5 degrees. A sample within one unit of its nearest row is kept as it is; one
    farther is moved onto that row. Returns (xy, yaw, pitch, joint vector of the row, distance in
    units), or None when the region holds no row."""
    q, x = table
    vals = np.array([*target_xy, yaw, pitch], dtype=np.float64)
    found = nearest(x, vals, region)
    if found is None:
        return None
    i, d = found
    if d <= 1.0:
        return (float(vals[0]), float(vals[1])), float(yaw), float(pitch), q[i].copy(), d
    return (float(x[i, 0]), float(x[i, 1])), float(x[i, 2]), float(x[i, 3]), q[i].copy(), d
