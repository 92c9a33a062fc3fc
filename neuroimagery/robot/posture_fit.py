"""The small inverse-kinematics fit that places the four initial postures (docs/robot.md).

For each posture: the joint vector whose rake head plate has its centre at a target point of the
table, its lowest point 5 mm above the table, and the rake's orientation of a reference joint
vector (the plate upright and spanning left-right at posture 1), with every joint at least 12 % of
its range from its limits. ``python -m neuroimagery.robot.posture_fit`` prints the fitted
postures and the scene criteria they meet or fail (``robot.scene_check``).
"""
from __future__ import annotations


import numpy as np
import torch

from .config import WorldConfig


def fit_posture(cfg: WorldConfig, target_xy, q_ref, clearance: float = 0.005, margin: float = 0.12) -> np.ndarray:
    from scipy.optimize import least_squares

    from .kinematics import ArmKinematics
    from .scene_check import plate_points

    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    lim = kin.joint_limits.double().numpy()
    lo = lim[:, 0] + margin * (lim[:, 1] - lim[:, 0])
    hi = lim[:, 1] - margin * (lim[:, 1] - lim[:, 0])
    plate = plate_points(cfg)
    centre = np.array([*cfg.rake_head_offset, 1.0])
    R_ref = kin.rake_pose_np(np.asarray(q_ref, dtype=np.float64)[None])[0][:3, :3]

    def res(q):
        T = kin.rake_pose_np(q[None])[0]
        c = T @ centre
        low = (plate @ T.T)[:, 2].min()
        return np.concatenate([(c[:2] - np.asarray(target_xy)) / 0.002, [(low - cfg.table_top - clearance) / 0.002],
                               (T[:3, :3] - R_ref).ravel() / 0.05])

    q0 = np.clip(np.asarray(q_ref, dtype=np.float64), lo, hi)
    return least_squares(res, q0, bounds=(lo, hi)).x


def main() -> int:
    from .config import DEFAULT_POSTURES
    from .scene_check import check_scene, scene_geometry

    cfg = WorldConfig()
    # targets: the plate centres of the four situations (docs/robot.md, "Initial postures"; chosen by the
    # rule of docs/choices.md); the
    # references for the orientation: the stored postures
    targets = [(0.645, -0.135), (0.60, -0.26), (0.55, -0.26), (0.54, -0.37)]
    fitted = tuple(tuple(round(float(v), 3) for v in fit_posture(cfg, t, q)) for t, q in zip(targets, DEFAULT_POSTURES))
    print("POSTURES =", fitted)
    new = WorldConfig(postures=fitted)
    for row in scene_geometry(new):
        print(row)
    print("\n".join(check_scene(new)) or "all scene criteria met")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
