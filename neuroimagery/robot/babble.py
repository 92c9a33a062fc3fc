"""Measure Table 7.1 (events part) by random motor babbling from each initial posture.

    python -m neuroimagery.robot.babble --rollouts N --out DIR [--seed S]

From every posture, ``N`` random DMPs are rolled out (goals = the posture plus Gaussian noise
bounded to ``WorldConfig.max_goal_offset_rad``, random shape weights; the Fig. 7.5 exploration step) with no event watched, so every event that
happens is recorded.  An event counts as reachable from a posture when at least one rollout fired
it.  Writes ``DIR/table_7_1.json`` ({"posture-1": {"events": [0/1 x 6], "rates": [...],
"rollouts": N}, ...} in ``EVENTS`` order) and ``DIR/table_7_1.md`` next to the thesis's table.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import torch

from neuroimagery.errors import UserInputError
from neuroimagery.motor.dmp import DMP
from neuroimagery.robot.world import EVENTS, ToolWorld

# Table 7.1 of the thesis, events part (retrieve, touch, south, north, west, east).
THESIS_EVENTS = {
    "posture-1": [1, 0, 1, 0, 1, 0],
    "posture-2": [0, 1, 1, 0, 1, 0],
    "posture-3": [0, 1, 1, 1, 1, 1],
    "posture-4": [0, 1, 1, 1, 1, 1],
}
THESIS_SKILLS = {
    "posture-1": [1, 0, 1, 0, 1, 0],
    "posture-2": [1, 1, 1, 0, 1, 0],
    "posture-3": [0, 1, 1, 1, 1, 1],
    "posture-4": [0, 1, 1, 1, 1, 1],
}


@dataclass(frozen=True)
class BabbleConfig:
    """Random exploration around a posture (Fig. 7.5, "adding noise to the goal parameters")."""

    goal_sigma: float = 0.35  # rad, std of the goal noise around the initial posture
    weight_sigma: float = 300.0  # std of the random shape weights
    duration_s: float = 1.5  # movement duration (DMP time constant)
    dt: float = 0.02  # trajectory step (= WorldConfig.control_dt)

    def __post_init__(self) -> None:
        for key in ("goal_sigma", "weight_sigma", "duration_s", "dt"):
            if not getattr(self, key) >= 0 or (key in ("duration_s", "dt") and getattr(self, key) <= 0):
                raise ValueError(f"BabbleConfig.{key} must be positive, got {getattr(self, key)}")


def random_thetas(
    world: ToolWorld, dmp: DMP, posture: int, n: int, cfg: BabbleConfig, generator: torch.Generator
) -> torch.Tensor:
    """``n`` random DMP parameter vectors around ``posture``.

    Goals: the posture plus N(0, goal_sigma) noise, bounded to the movement's reach
    (``WorldConfig.max_goal_offset_rad``) and clipped to the joint limits.
    """
    q0 = world.initial_posture(posture)
    b = world.cfg.max_goal_offset_rad
    noise = (cfg.goal_sigma * torch.randn(n, 7, generator=generator)).clamp(-b, b)
    goals = world.kin.clamp(q0 + noise)
    weights = cfg.weight_sigma * torch.randn(n, 7, dmp.n_basis, generator=generator)
    return dmp.pack(goals, weights)


def world_dmp(world: ToolWorld) -> DMP:
    """The DMP of this world's movements: goals bounded to ``WorldConfig.max_goal_offset_rad``."""
    return DMP(max_goal_offset=world.cfg.max_goal_offset_rad)


def trajectories(world: ToolWorld, dmp: DMP, theta: torch.Tensor, posture: int, cfg: BabbleConfig) -> torch.Tensor:
    """DMP rollouts from ``posture`` clipped to the URDF joint limits: (N, T, 7).

    The goals are bounded to the world's ``max_goal_offset_rad`` around the posture whatever
    ``dmp``'s own bound.
    """
    q0 = world.initial_posture(posture)
    g, w = dmp.split(theta if theta.dim() == 2 else theta[None])
    b = world.cfg.max_goal_offset_rad
    theta = dmp.pack(q0 + (g - q0).clamp(-b, b), w)
    return world.kin.clamp(dmp.rollout(theta, q0, cfg.duration_s, cfg.dt))


def measure(n_rollouts: int, seed: int = 0, cfg: BabbleConfig | None = None, world: ToolWorld | None = None) -> dict:
    """Babble ``n_rollouts`` times from each posture; return the table (see module docstring)."""
    if n_rollouts < 1:
        raise UserInputError(f"--rollouts must be >= 1, got {n_rollouts}")
    cfg = cfg or BabbleConfig()
    own = world is None
    world = world or ToolWorld()
    dmp = world_dmp(world)
    gen = torch.Generator().manual_seed(seed)
    table: dict = {}
    try:
        for k in range(1, 5):
            theta = random_thetas(world, dmp, k, n_rollouts, cfg, gen)
            outs = []
            for chunk in torch.split(theta, 50):
                outs += world.rollout(trajectories(world, dmp, chunk, k, cfg), k, watched=None)
            counts = torch.tensor([o.events for o in outs], dtype=torch.float32).sum(0)
            table[f"posture-{k}"] = {
                "events": [int(c > 0) for c in counts],
                "rates": [round(float(c) / n_rollouts, 4) for c in counts],
                "rollouts": n_rollouts,
                "blew_up": sum(o.blew_up for o in outs),
                "simulated": sum(o.simulated for o in outs),
            }
    finally:
        if own:
            world.close()
    return table


def markdown(table: dict) -> str:
    """Measured events beside the thesis's, cell by cell (``1/0`` measured, ``*`` = disagrees)."""
    head = "| posture | " + " | ".join(EVENTS) + " | agree |\n|---|" + "---|" * (len(EVENTS) + 1) + "\n"
    rows = []
    for key, row in table.items():
        thesis = THESIS_EVENTS[key]
        cells = [
            f"{m}{'' if m == t else '*'} ({r:.1%})" for m, t, r in zip(row["events"], thesis, row["rates"])
        ]
        agree = sum(m == t for m, t in zip(row["events"], thesis))
        rows.append(f"| {key} | " + " | ".join(cells) + f" | {agree}/6 |\n")
    note = (
        "\nCells: measured reachability (1 = fired in at least one rollout), share of rollouts in "
        "brackets; `*` marks a cell that differs from thesis Table 7.1.\n"
    )
    thesis_rows = "".join(f"| {k} | " + " | ".join(map(str, v)) + " |\n" for k, v in THESIS_EVENTS.items())
    return (
        "### Measured (random babbling)\n\n" + head + "".join(rows) + note
        + "\n### Thesis Table 7.1, events\n\n| posture | " + " | ".join(EVENTS) + " |\n|---|"
        + "---|" * len(EVENTS) + "\n" + thesis_rows
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m neuroimagery.robot.babble", description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=int, default=200, help="random DMPs per posture")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    try:
        t0 = time.perf_counter()
        table = measure(args.rollouts, args.seed)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "table_7_1.json").write_text(json.dumps(table, indent=2))
        (args.out / "table_7_1.md").write_text(markdown(table))
        print(markdown(table))
        print(f"wrote {args.out / 'table_7_1.json'} in {time.perf_counter() - t0:.1f} s")
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
