"""From which side of the toy the rake's plate first comes near it, per initial posture (FK only).

    python benchmarks/exp5_approach.py [--rollouts N] [--grid]

For each posture, N exploration movements (the rule of docs/contracts.md W9: the posture plus the
goal noise, random shape weights; stream seed 7) are put through forward kinematics only (no
physics, so the toy does not move). A movement's *first approach* is the side of the toy (north,
south, west, east; by the larger of the offsets in x and y) of the plate points that are first
within 3 cm of the toy's box below its top less 1 cm; "none" if no plate point ever is. A toy can
be pulled south only by a plate that comes from its north side first, pushed east only by one that
comes from its west side (docs/contracts.md, Experiment 5, derived rules). With ``--grid`` the same
is measured for posture 4 moved to plate centres on a grid on the robot's side of the toy's far
face (the rake's handle pointing straight ahead, ``robot.posture_fit.fit_posture_heading``).
"""
from __future__ import annotations

import argparse
import math
from types import SimpleNamespace

import numpy as np
import torch

from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.kinematics import ArmKinematics
from neuroimagery.robot.posture_fit import HEADING_STARTS, fit_posture_heading
from neuroimagery.robot.movements import MovementConfig, explore, random_primitives, trajectories, world_dmp
from neuroimagery.robot.scene_check import plate_points, scene_geometry

SIDES = ("north", "south", "west", "east", "none")


def first_approach(kin, cfg, q, n: int, seed: int = 7, margin: float = 0.03) -> dict[str, float]:
    """Share of ``n`` exploration movements from joint vector ``q`` whose plate first nears each side."""
    world = SimpleNamespace(kin=kin, cfg=cfg)
    dmp, mc = world_dmp(), MovementConfig()
    gen = torch.Generator().manual_seed(seed)
    q0 = torch.tensor(q, dtype=torch.float32)
    theta = explore(world, dmp, random_primitives(world, dmp, n, mc, gen), q0, gen)
    poses = kin.rake_pose_np(trajectories(world, dmp, theta, q0, mc).double().numpy())
    pts = np.einsum("ntij,pj->ntpi", poses, plate_points(cfg)[::7])[..., :3]
    (tx, ty), h = cfg.toy_xy, cfg.toy_size / 2
    dx, dy = pts[..., 0] - tx, pts[..., 1] - ty
    low = pts[..., 2] < cfg.table_top + cfg.toy_size - 0.01
    near = low & (np.maximum(np.abs(dx), np.abs(dy)) < h + margin)
    side = np.where(np.abs(dx) >= np.abs(dy), np.where(dx > 0, 0, 1), np.where(dy > 0, 2, 3))
    counts = np.zeros(5)
    for i in range(n):
        hit = near[i].any(axis=1)
        if not hit.any():
            counts[4] += 1
            continue
        t = int(np.argmax(hit))
        counts[np.bincount(side[i, t][near[i, t]], minlength=4).argmax()] += 1
    return dict(zip(SIDES, counts / n))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=int, default=300)
    parser.add_argument("--grid", action="store_true")
    args = parser.parse_args()
    cfg = WorldConfig()
    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    print("| posture | " + " | ".join(SIDES) + " |\n|---|" + "---|" * len(SIDES))
    for k, q in enumerate(cfg.postures, start=1):
        share = first_approach(kin, cfg, q, args.rollouts)
        print(f"| {k} | " + " | ".join(f"{share[s]:.1%}" for s in SIDES) + " |")
    if not args.grid:
        return
    print("\n| plate centre | gap (m) | plate's farthest x | " + " | ".join(SIDES) + " |\n|---|---|---|" + "---|" * len(SIDES))
    for x in (0.52, 0.56):
        for y in (-0.40, -0.34, -0.28, 0.08, 0.14):
            q = fit_posture_heading(cfg, (x, y), 0.0, HEADING_STARTS)
            postures = list(cfg.postures)
            postures[3] = tuple(float(v) for v in q)
            g = scene_geometry(WorldConfig(postures=tuple(postures)))[3]
            if math.hypot(g["head_xy"][0] - x, g["head_xy"][1] - y) > 0.01:
                continue  # the arm cannot put the plate there with the handle straight ahead
            share = first_approach(kin, cfg, q, args.rollouts)
            print(f"| ({x}, {y}) | {g['gap']:.3f} | {g['plate_x_max']:.3f} | "
                  + " | ".join(f"{share[s]:.1%}" for s in SIDES) + " |")


if __name__ == "__main__":
    main()
