"""Why the table rule ``yield`` loses the pull from behind the toy (docs/world_acceptance.md, "With
the option table_contact = yield").

    python benchmarks/exp5_table_rules.py [--rollouts 1000] [--seed 0] [--posture 1]

The exploration movements of ``python -m neuroimagery.robot.babble``'s seed ``--seed`` from
``--posture`` (the streams of ``benchmarks/exp5_yield.py``), each run to its end in the world with
the lift (the default) and with the yield. Printed: how many retrieve and go south under each rule;
of the retrievals the yield loses, how many leave the toy within 5 mm of its start; and over those
movements (medians of each movement's largest value) how much lower the yield holds the rake's
grip, how much more it turns the rake, how far the plate's centre lies from where the lift puts it
and how much nearer the robot it comes at most.
"""
from __future__ import annotations

import argparse

import numpy as np
import torch

from exp5_yield import movements
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.world import ToolWorld

N_HANDLE = 11  # the first rake points lie on the handle, the rest on the plate (robot.world)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--posture", type=int, default=1, choices=(1, 2, 3, 4))
    args = parser.parse_args()
    torch.set_num_threads(1)
    with ToolWorld(WorldConfig()) as lift, ToolWorld(WorldConfig(table_contact="yield")) as yld:
        traj = movements(lift, args.posture, args.rollouts, args.seed)
        a, b = lift.rollout(traj, args.posture, None), yld.rollout(traj, args.posture, None)
        fired = {e: (np.array([o.fired(e) for o in a]), np.array([o.fired(e) for o in b])) for e in ("retrieve", "south")}
        for e, (x, y) in fired.items():
            print(f"{e}: lift {x.sum()}, yield {y.sum()} of {len(a)} movements")
        lost = np.flatnonzero(fired["retrieve"][0] & ~fired["retrieve"][1])
        still = sum(np.hypot(*b[i].toy_displacement) <= 0.005 for i in lost)
        print(f"retrievals the yield loses: {len(lost)}; the toy moves at most 5 mm in {still} of them")
        if not len(lost):
            return
        pa, pb = lift._plan(traj.numpy()), yld._plan(traj.numpy())
        Ra, Rb = pa["poses"][lost, :, :3, :3], pb["poses"][lost, :, :3, :3]
        turn = np.degrees(np.arccos(np.clip((np.einsum("ntij,ntij->nt", Ra, Rb) - 1) / 2, -1, 1)))
        lower = pa["poses"][lost, :, 2, 3] - pb["poses"][lost, :, 2, 3]
        ca, cb = pa["pts"][lost][..., N_HANDLE:, :].mean(-2), pb["pts"][lost][..., N_HANDLE:, :].mean(-2)
        apart = np.linalg.norm(cb[..., :2] - ca[..., :2], axis=-1)
        nearer = ca[..., 0] - cb[..., 0]
        print(f"over those movements (median of each one's largest): grip lower by {100 * np.median(lower.max(1)):.1f} cm, "
              f"rake turned {np.median(turn.max(1)):.1f} deg more, plate centre {100 * np.median(apart.max(1)):.1f} cm "
              f"from the lift's, nearer the robot by {100 * np.median(nearer.max(1)):.1f} cm")


if __name__ == "__main__":
    main()
