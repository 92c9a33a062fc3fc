"""The leak of Experiment 4's accumulator PMCd, fixed per participant after training by rule R2 of
docs/choices.md: the smallest leak with which the misaligned pairs the training set shows of each
object stay quiet (contract X4.12 (b)). It reads how the set is built (object and angle of each image),
never an appearance or a YES/NO label."""
from __future__ import annotations

import torch

LEAK_STEP = 0.05  # grid of the leak rule
LEAK_STEPS = 50  # its candidates: w, w + 0.05, ..., w + 2.5
QUIET_SHARE = 0.10  # largest share of held misaligned pairs that may decide
LEAK_CHUNK = 8  # values of k held at a time


def misaligned_pairs(objects: torch.Tensor, angles: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Every image against every image of the same object at another angle (both appearances, the
    appearance not read) -> (target rows, comparison rows)."""
    ti, ci = torch.meshgrid(torch.arange(len(objects)), torch.arange(len(objects)), indexing="ij")
    ti, ci = ti.reshape(-1), ci.reshape(-1)
    keep = (objects[ti] == objects[ci]) & ((angles[ti] - angles[ci]).abs() > 1e-6)
    return ti[keep], ci[keep]


@torch.no_grad()
def leak_by_rule(model, x: torch.Tensor, objects: torch.Tensor, angles: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Each participant's leak ``(P,)`` and the gain at it: on a grid of ``LEAK_STEP`` from w, the
    smallest k with which at most ``QUIET_SHARE`` of the misaligned same-object pairs of the maps ``x``
    ``(P, N, n)`` decide (either way), their still-step evidence held from rest for
    ``selection.max_steps`` steps, the gain at each k ``model.gain_for(k)``; where no k does, the k
    with the fewest deciding. The grid is held ``LEAK_CHUNK`` values of k at a time, as one batch
    (each pair's race depends on its own evidence, gain and leak alone), until every participant
    has its k: a larger k changes nothing once one is found."""
    P = x.shape[0]
    t, c = misaligned_pairs(objects, angles)
    ev = model.pair_evidence(x[:, t], x[:, c])
    grid = torch.tensor([float(model.p.lca.w) + LEAK_STEP * i for i in range(LEAK_STEPS + 1)])
    leak, best = torch.full((P,), float(model.p.lca.k)), torch.full((P,), float("inf"))
    gain = torch.full((P,), float("nan"))
    done = torch.zeros(P, dtype=torch.bool)
    for lo in range(0, len(grid), LEAK_CHUNK):
        ks = grid[lo:lo + LEAK_CHUNK].unsqueeze(1).expand(-1, P)  # (K, P)
        gains = model.gain_for(ks)
        shares = model.hold(ev, gain=gains, leak=ks).decided.float().mean(-1)  # (K, P)
        for k, g, share in zip(ks, gains, shares):
            better = ~done & (share < best - 1e-9)
            leak, best, gain = torch.where(better, k, leak), torch.where(better, share, best), torch.where(better, g, gain)
            done = done | (share <= QUIET_SHARE)
        if bool(done.all()):
            break
    unset = gain.isnan()  # no k was better than none (no misaligned pair to hold): the gain at the default leak
    return leak, torch.where(unset, model.gain_for(leak), gain) if bool(unset.any()) else gain
