"""An arm that yields to the table (``WorldConfig.table_contact = "yield"``; docs/robot.md, "The
table and the arm").

The seven arm joints are springs of equal stiffness about the commanded joints and the table is
rigid, frictionless and pushes only upward.  Where the command would put a rake point below
``table_top + table_clearance``, the arm takes the joints nearest the command (least sum of squared
changes) that rest the rake on the table.  An upward push ``f`` at the rake's lowest point ``p``
moves equal springs by ``f * dz_p/dq``, so the change lies along the gradient of that point's
height; :func:`yield_joints` first projects the command onto the lowest point's linearised
constraint (Gauss-Newton steps toward the least change), then lifts what still sinks by the
least change from where the arm is (``deficit * g / |g|^2``), a joint at a limit that a step would
push beyond it held there.  Where no such joints exist within the limits, the arm cannot yield
(``ok`` False) and the table stops it (:func:`robot.rake_plan.held_steps`).
"""
from __future__ import annotations

import numpy as np

from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.rake_plan import below_floor, held_steps

YIELD_TOLERANCE = 0.001  # m: a rake point this little below the table counts as resting on it
STAGES = 4  # the Gauss-Newton projection raises the floor in this many equal parts
CORRECTIONS = 4  # lifting steps from where the arm is, after the projection


def yield_joints(kin, q: np.ndarray, points: np.ndarray, point_radius: np.ndarray, cfg: WorldConfig,
                 iters: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commanded joints ``q`` (M, 7) -> the joints the yielding arm takes (M, 7), whether they rest
    the rake on the table within ``YIELD_TOLERANCE`` (M,) bool, and their rake poses (M, 4, 4).

    A command that does not sink is returned unchanged.  ``kin`` is the world's
    :class:`~neuroimagery.robot.kinematics.ArmKinematics`; ``points`` (P, 3) and
    ``point_radius`` (P,) the rake's sample points in its frame.
    """
    lim = kin.joint_limits.detach().double().cpu().numpy()
    lo, hi = lim[:, 0], lim[:, 1]
    floor = cfg.table_top + cfg.table_clearance
    q0 = np.array(q, dtype=np.float64, copy=True)
    qy = q0.copy()
    rows = np.arange(len(qy))
    depth0 = None
    for it in range(iters + 1):
        poses, axis, point = kin.rake_frames_np(qy, joints=True)
        pts, below = below_floor(poses, points, point_radius, floor)
        worst = below.argmax(axis=-1)
        deficit = below[rows, worst]
        if depth0 is None:
            depth0 = np.maximum(deficit, 0.0)
        if it == iters:
            break
        p = pts[rows, worst]  # (M, 3) the lowest point
        g = np.cross(axis, p[:, None, :] - point)[..., 2]  # d z_p / d q  (M, 7)
        held = ((qy <= lo + 1e-9) & (g < 0)) | ((qy >= hi - 1e-9) & (g > 0))
        g = np.where(held, 0.0, g)
        n2 = np.maximum((g * g).sum(axis=-1), 1e-12)
        if it < iters - CORRECTIONS:
            # the point of least change from the command on the lowest point's linearised
            # constraint (Gauss-Newton: q0 + a g), the floor raised in STAGES equal parts of the
            # first depth so that each stage starts near its solution
            stage = min(it * STAGES // (iters - CORRECTIONS) + 1, STAGES)
            short = deficit - (1.0 - stage / STAGES) * depth0
            a = np.maximum(short + (g * (qy - q0)).sum(axis=-1), 0.0) / n2
            qy = np.clip(q0 + a[:, None] * g, lo, hi)
        else:
            # what still sinks (another point lowest, a joint at its limit): the least change
            # that lifts the lowest point from where the arm is
            a = np.maximum(deficit, 0.0) / n2
            qy = np.clip(qy + a[:, None] * g, lo, hi)
    return qy, deficit <= YIELD_TOLERANCE, poses


def yielded_poses(kin, q: np.ndarray, geo, cfg: WorldConfig) -> tuple[np.ndarray, np.ndarray]:
    """Joint trajectories ``q`` (N, T, 7) -> the rake poses the yielding arm gives (N, T, 4, 4)
    and the step whose joints the arm holds (N, T): from the first step it cannot yield, the
    pose of the step before (``rake_plan.held_steps``).  ``geo`` is the world's
    ``rake_plan.RakeGeometry``."""
    lead = q.shape[:-1]
    flat = np.asarray(q, dtype=np.float64).reshape(-1, 7)
    poses = kin.rake_pose_np(flat)
    _, below = below_floor(poses, geo.points, geo.point_radius, cfg.table_top + cfg.table_clearance)
    sink = below.max(axis=-1) > 0
    ok = np.ones(len(flat), dtype=bool)
    if sink.any():
        _, ok[sink], poses[sink] = yield_joints(kin, flat[sink], geo.points, geo.point_radius, cfg)
    poses, ok = poses.reshape(*lead, 4, 4), ok.reshape(lead)
    arm = held_steps(ok)
    return np.take_along_axis(poses, arm[..., None, None], axis=1), arm
