"""The leak of Experiment 4's accumulator PMCd, fixed per participant after training by rule R2 of
docs/choices.md: the smallest leak with which the misaligned pairs the training set shows of each
object stay quiet (contract X4.12 (b)). It reads how the set is built (object and angle of each image),
never an appearance or a YES/NO label."""
from __future__ import annotations

import torch

LEAK_STEP = 0.05  # grid of the leak rule
LEAK_STEPS = 50  # its candidates: w, w + 0.05, ..., w + 2.5
QUIET_SHARE = 0.10  # largest share of held misaligned pairs that may decide


def misaligned_pairs(objects: torch.Tensor, angles: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Every image against every image of the same object at another angle (both appearances, the
    appearance not read) -> (target rows, comparison rows)."""
    ti, ci = torch.meshgrid(torch.arange(len(objects)), torch.arange(len(objects)), indexing="ij")
    ti, ci = ti.reshape(-1), ci.reshape(-1)
    keep = (objects[ti] == objects[ci]) & ((angles[ti] - angles[ci]).abs() > 1e-6)
    return ti[keep], ci[keep]


@torch.no_grad()
def leak_by_rule(model, x: torch.Tensor, objects: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """Each participant's leak ``(P,)``: on a grid of ``LEAK_STEP`` from w, the smallest k with which at
    most ``QUIET_SHARE`` of the misaligned same-object pairs of the maps ``x`` ``(P, N, n)`` decide
    (either way), their still-step evidence held from rest for ``selection.max_steps`` steps, the gain
    at each k ``model.gain_for(k)``; where no k does, the k with the fewest deciding."""
    P = x.shape[0]
    t, c = misaligned_pairs(objects, angles)
    ev = model.pair_evidence(x[:, t], x[:, c])
    leak, best = torch.full((P,), float(model.p.lca.k)), torch.full((P,), float("inf"))
    done = torch.zeros(P, dtype=torch.bool)
    for i in range(LEAK_STEPS + 1):
        k = torch.full((P,), float(model.p.lca.w) + LEAK_STEP * i)
        share = model.hold(ev, gain=model.gain_for(k), leak=k).decided.float().mean(1)
        better = ~done & (share < best - 1e-9)
        leak, best = torch.where(better, k, leak), torch.where(better, share, best)
        done = done | (share <= QUIET_SHARE)
    return leak
