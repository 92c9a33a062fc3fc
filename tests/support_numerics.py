"""Comparing two computations of the same numbers that may round differently (other shapes, other
kernels, other CPUs): values within a rounding bound (``neuroimagery.nn.numerics``), and the
discrete outcomes drawn from them (winners, thresholded maps) identical wherever the bound
decides them."""
from __future__ import annotations

import torch


def assert_within(got: torch.Tensor, ref: torch.Tensor, bound, what: str = "") -> None:
    """Every ``|got - ref|`` at most ``bound`` (broadcastable)."""
    excess = (got.double() - ref.double()).abs() - torch.as_tensor(bound, dtype=torch.float64)
    worst = float(excess.max()) if excess.numel() else 0.0
    assert worst <= 0, f"{what}: differs by {worst:.3g} more than the rounding bound somewhere"


def assert_same_winner(winner: torch.Tensor, scores: torch.Tensor, bound, largest: bool = True, what: str = "") -> None:
    """``winner`` (``scores.shape[:-1]``), computed otherwise from numbers within ``bound`` of
    ``scores``, is a unit whose score is within ``2 bound`` of the best: the best unit itself
    wherever the runner-up is further away than that, and one of the units tied up to rounding
    elsewhere (which one depends on the rounding)."""
    s = scores.double() if largest else -scores.double()
    b = torch.as_tensor(bound, dtype=torch.float64).expand_as(s)
    best = s.amax(-1)
    picked = s.gather(-1, winner.unsqueeze(-1)).squeeze(-1)
    slack = 2 * b.amax(-1)
    assert bool((picked >= best - slack).all()), f"{what}: a winner that rounding cannot explain"
    decided = (s >= (best - slack).unsqueeze(-1)).sum(-1) == 1
    assert torch.equal(winner[decided], s.argmax(-1)[decided]), what


def assert_same_threshold(got: torch.Tensor, ref: torch.Tensor, level: float, margin, what: str = "") -> None:
    """``got >= level`` equals ``ref >= level`` wherever ``ref`` is further than ``margin`` (the
    most ``got`` and ``ref`` may differ) from the level."""
    decided = (ref.double() - level).abs() > torch.as_tensor(margin, dtype=torch.float64)
    assert torch.equal((got >= level)[decided], (ref >= level)[decided]), what
