"""Measurements shared by the Experiment 3 and 4 contract tests (docs/contracts.md)."""
from __future__ import annotations

import torch

from neuroimagery.nn import SOM
from neuroimagery.vision.edges import iou, rotate


def rule_rate(eta: float = 0.1, active: int = 75, n_in: int = 1024, seed: int = 0) -> float:
    """X3.1 / X4.1: one supervised step of a sum-1 map on a binary image of ``active`` units;
    ``|w' - w|_1 / |x' - w|_1`` with ``x'`` the image scaled to sum 1."""
    g = torch.Generator().manual_seed(seed)
    som = SOM((4,), n_in, seed=seed, init=(0.0, 0.01), eta=eta, eta_final=eta, sigma=1e-3, sigma_final=1e-3,
              iterations=10, supervised=True)
    som.weight.div_(som.weight.sum(-1, keepdim=True))
    x = torch.zeros(1, n_in)
    x[0, torch.randperm(n_in, generator=g)[:active]] = 1.0
    w0 = som.weight[0, 1].clone()
    som.step(x, torch.tensor([1]))
    xs = x[0] / x[0].sum()
    return float((som.weight[0, 1] - w0).abs().sum() / (xs - w0).abs().sum())


def forward_fn(trained, move: int):
    """One forward-model step of ``trained.model`` with the same move for every row of a
    ``(P or 1, B, units)`` batch (the shape probes of X3.7 / X4.6)."""
    m, P = trained.model, trained.model.participants

    def fn(x):
        x = x.expand(P, -1, -1) if x.shape[0] == 1 else x
        return m.forward_step(x, torch.full(x.shape[:2], move, dtype=torch.long))
    return fn


def banks_maps(bank) -> torch.Tensor:
    return bank.maps


def item_rows(bank, appearance=None):
    """Rows of ``bank`` as (row, object, angle, appearance)."""
    return [(i, o, float(a), ap) for i, (o, a, ap) in enumerate(bank.items) if appearance is None or ap == appearance]


def forward_model_shape(step_fn, maps: torch.Tensor, step_deg: float, size: int, steps: int = 2) -> dict:
    """X3.7 / X4.6: IoU of the imagined map after k steps with the true rotation at k steps and at
    k +- 1 steps, and the active-unit ratio at k = 1 (means over images and participants)."""
    x = maps.reshape(-1, size, size)
    cur = maps.unsqueeze(0)
    out = {}
    for k in range(1, steps + 1):
        cur = step_fn(cur)
        img = cur.reshape(cur.shape[0], -1, size, size)
        truth = {j: rotate(x, j * step_deg).unsqueeze(0) for j in (k - 1, k, k + 1)}
        out[k] = {j: float(iou(img, t).mean()) for j, t in truth.items()}
        if k == 1:
            out["ratio"] = float(img.sum((-2, -1)).mean() / truth[1].sum((-2, -1)).mean())
    return out
