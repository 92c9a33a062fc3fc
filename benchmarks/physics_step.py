"""Convergence of the tool-use world's physics step (docs/robot.md, physics step criterion).

    python benchmarks/physics_step.py [--rollouts-per-posture 400]

Rolls the same random DMPs (the goal noise rule, stream ``77 + posture``) out with every value of
``WorldConfig.max_substep_travel`` on the ladder 8, 4, 2, 1, 0.5, 0.25 mm, and with the fixed two
10 ms steps (``None``). For each value it prints how many rollouts fire a different set of events
than at half that value, the median difference of the toy's displacement (rollouts where the toy
moved), the events fired, the toys thrown off the table, the blow-ups, and the time. The rule:
the largest value at which halving it changes the events of at most 1 % of the rollouts.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from neuroimagery.core.arguments import ToolParser, check, check_size, count, run_tool
from neuroimagery.robot.movements import MovementConfig, goal_noise, random_primitives, trajectories, world_dmp
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.events import EVENTS
from neuroimagery.robot.world import ToolWorld

LADDER = (0.008, 0.004, 0.002, 0.001, 0.0005, 0.00025)
CHANGED_AT_MOST = 0.01


def outcomes(travel: float | None, per_posture: int) -> tuple[np.ndarray, np.ndarray, float, int, int]:
    """Events (R, 6), toy displacements (R, 2), seconds of rollouts, toys thrown off the table and
    blow-ups at one physics step."""
    world = ToolWorld(WorldConfig(max_substep_travel=travel))
    cfg, dmp = MovementConfig(), world_dmp()
    events, disp, seconds, off, blew = [], [], 0.0, 0, 0
    try:
        for posture in range(1, 5):
            gen = torch.Generator().manual_seed(77 + posture)
            theta = goal_noise(world, dmp, random_primitives(world, dmp, per_posture, cfg, gen), gen)
            traj = trajectories(world, dmp, theta, world.initial_posture(posture), cfg)
            t0 = time.perf_counter()
            out = world.rollout(traj, posture, watched=None)
            seconds += time.perf_counter() - t0
            events += [o.events for o in out]
            disp += [o.toy_displacement for o in out]
            off += sum(o.off_table for o in out)
            blew += sum(o.blew_up for o in out)
    finally:
        world.close()
    return np.asarray(events, dtype=bool), np.asarray(disp, dtype=float), seconds, off, blew


def main(argv: list[str] | None = None) -> int:
    ap = ToolParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rollouts-per-posture", type=count, default=400)
    ap.add_argument("--allow-large", action="store_true", help="allow more than 100000 rollouts per posture")
    args = ap.parse_args(argv)
    check("--rollouts-per-posture", args.rollouts_per_posture, ge=1)
    check_size("--rollouts-per-posture", args.rollouts_per_posture, 100_000, args.allow_large)
    runs = {v: outcomes(v, args.rollouts_per_posture) for v in (None, *LADDER)}
    print(f"events fired, in order {', '.join(EVENTS)}")
    print("| max_substep_travel | rollouts whose events change at half the value | median displacement change (cm) | events fired | off the table | blow-ups | rollout time (s) |")
    print("|---|---|---|---|---|---|---|")
    chosen = None
    for v, (ev, d, sec, off, blew) in runs.items():
        name = "fixed 2 x 10 ms" if v is None else f"{v * 1000:g} mm"
        half = LADDER[0] if v is None else v / 2  # the fixed step is compared with the ladder's top
        changed, dchange = "-", "-"
        if half in runs:
            ev2, d2 = runs[half][:2]
            n = int((ev != ev2).any(axis=1).sum())
            moved = (np.linalg.norm(d, axis=1) > 0.005) | (np.linalg.norm(d2, axis=1) > 0.005)
            med = float(np.median(np.linalg.norm(d - d2, axis=1)[moved])) * 100 if moved.any() else 0.0
            changed, dchange = f"{n} of {len(ev)} ({n / len(ev):.1%})", f"{med:.2f}"
            if v is not None and chosen is None and n <= CHANGED_AT_MOST * len(ev):
                chosen = v
        print(f"| {name} | {changed} | {dchange} | {ev.sum(axis=0).tolist()} | {off} | {blew} | {sec:.2f} |")
    if chosen is None:
        print(f"no value on the ladder changes the events of at most {CHANGED_AT_MOST:.0%} of the rollouts when halved")
    else:
        print(f"largest value meeting the criterion: {chosen * 1000:g} mm")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
