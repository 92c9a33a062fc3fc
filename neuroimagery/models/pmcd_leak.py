"""The leak of Experiment 4's accumulator PMCd, fixed per participant after training by the rule of
docs/contracts.md ("Accumulator leak", contract X4.12): PMCd treated as a detector of alignment, on
the pairs the training set shows of each object."""
from __future__ import annotations

import torch

LEAK_STEP = 0.05  # grid of the leak rule
LEAK_STEPS = 50  # its candidates: w, w + 0.05, ..., w + 2.5
QUIET_SHARE = 0.10  # X4.12: largest share of held misaligned pairs that may decide


def object_pairs(objects: torch.Tensor, mirror: torch.Tensor, angles: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The pairs a set shows of one object, from how it is built (per row: object index, mirror flag,
    angle): every basic image as the target against every image of the same object, basic or
    mirror -> (target rows, comparison rows, aligned: the same angle)."""
    t = (~mirror).nonzero().squeeze(-1)
    ti, ci = torch.meshgrid(t, torch.arange(len(objects)), indexing="ij")
    ti, ci = ti.reshape(-1), ci.reshape(-1)
    keep = objects[ti] == objects[ci]
    ti, ci = ti[keep], ci[keep]
    return ti, ci, (angles[ti] - angles[ci]).abs() < 1e-6


def turned_pairs(model, x: torch.Tensor, t: torch.Tensor, c: torch.Tensor, angles: torch.Tensor,
                 mirror: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The still-step evidence ``(P, B, 2)`` of the pairs ``t``, ``c`` of maps ``x`` ``(P, N, n)``
    once each comparison is turned to its target's angle by ``model``'s forward models (the
    required steps, the short way round), and the right answer of each (0 YES, 1 NO for a mirror)."""
    d = (angles[c] - angles[t] + 180.0) % 360.0 - 180.0  # comparison minus target, in [-180, 180)
    n = (d.abs() / float(model.p.step_deg)).round().long()
    move = torch.where(d > 0, 2, 0)  # Mr turns by -step, Ml by +step
    img = x[:, c]
    P = x.shape[0]
    for s in range(int(n.max()) if len(n) else 0):
        live = (n > s).unsqueeze(0).expand(P, -1)
        img = torch.where(live.unsqueeze(-1), model.forward_step(img, move.expand(P, -1), live), img)
    return model.pair_evidence(x[:, t], img), mirror[c].long()


@torch.no_grad()
def leak_by_rule(model, x: torch.Tensor, objects: torch.Tensor, mirror: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """Each participant's leak ``(P,)``: on a grid of ``LEAK_STEP`` from w, the smallest k that
    minimises the share of misaligned same-object pairs of the maps ``x`` ``(P, N, n)`` that decide,
    their still-step evidence held for ``selection.max_steps`` steps, plus the share of pairs turned
    to alignment by the forward models that do not give the right answer held as long; the gain at
    each k is ``model.gain_for(k)``."""
    P = x.shape[0]
    t, c, aligned = object_pairs(objects, mirror, angles)
    misaligned = model.pair_evidence(x[:, t[~aligned]], x[:, c[~aligned]])
    turned, right = turned_pairs(model, x, t, c, angles, mirror)
    leak, best = torch.full((P,), float(model.p.lca.k)), torch.full((P,), float("inf"))
    for i in range(LEAK_STEPS + 1):
        k = torch.full((P,), float(model.p.lca.w) + LEAK_STEP * i)
        gain = model.gain_for(k)
        wrong = model.hold(misaligned, gain=gain, leak=k).decided.float().mean(1)
        h = model.hold(turned, gain=gain, leak=k)
        missed = 1.0 - (h.decided & (h.winner == right)).float().mean(1)
        err = wrong + missed
        better = err < best - 1e-6  # ties keep the smaller k
        leak, best = torch.where(better, k, leak), torch.where(better, err, best)
    return leak
