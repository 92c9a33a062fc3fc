"""Whether the arm can yield to the table under ``table_contact = yield`` (docs/robot.md, "The table
and the arm": part (a) of the rule for the default).

    python benchmarks/exp5_arm_yield.py [--rollouts 2000] [--seed 0]

For each posture, the exploration movements of ``python -m neuroimagery.robot.babble``'s seed
``--seed`` (the world's exploration rule W9, each movement to its end, no physics; the streams of
``benchmarks/exp5_yield.py``): the control steps whose commanded rake would sink into the table,
the share at which the yielding arm (``robot.arm_yield``) finds joints within the limits that rest
the rake on the table, the movements it stops, the largest joint change (median and 90th
percentile, degrees), the rake's turn against the command (degrees) and the solver's time.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from exp5_yield import movements
from neuroimagery.robot import arm_yield, rake_plan
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.world import ToolWorld


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    sinking = yielded = 0
    print("| posture | sinking steps (share) | arm yields | movements stopped | largest joint change, median / 90th pct (deg) "
          "| rake turned, median / 90th pct (deg) | solver (s) |\n|---|---|---|---|---|---|---|", flush=True)
    with ToolWorld(WorldConfig(table_contact="yield")) as w:
        geo, cfg = w._geometry, w.cfg
        for k in (1, 2, 3, 4):
            traj = movements(w, k, args.rollouts, args.seed).double().numpy()
            flat = traj.reshape(-1, 7)
            poses = w.kin.rake_pose_np(flat)
            _, below = rake_plan.below_floor(poses, geo.points, geo.point_radius, cfg.table_top + cfg.table_clearance)
            sink = below.max(axis=-1) > 0
            t0 = time.perf_counter()
            qy, ok, py = arm_yield.yield_joints(w.kin, flat[sink], geo.points, geo.point_radius, cfg)
            took = time.perf_counter() - t0
            every = np.ones(len(flat), dtype=bool)
            every[sink] = ok
            stopped = (~every.reshape(traj.shape[:2])).any(axis=1).mean()
            dq = np.degrees(np.abs(qy - flat[sink]).max(axis=-1)[ok])
            cos = (np.einsum("mij,mij->m", poses[sink][:, :3, :3], py[:, :3, :3]) - 1) / 2
            turn = np.degrees(np.arccos(np.clip(cos, -1, 1)))[ok]
            sinking += int(sink.sum())
            yielded += int(ok.sum())
            print(f"| {k} | {int(sink.sum())} ({sink.mean():.1%}) | {ok.mean():.4%} | {stopped:.2%} | "
                  f"{np.median(dq):.1f} / {np.percentile(dq, 90):.1f} | {np.median(turn):.1f} / {np.percentile(turn, 90):.1f} "
                  f"| {took:.1f} |", flush=True)
    print(f"\nall postures: the arm yields at {yielded} of {sinking} sinking steps ({yielded / max(sinking, 1):.4%})")


if __name__ == "__main__":
    main()
