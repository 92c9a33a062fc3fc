"""The chapter-6 image -> wrist-posture maps (C2/C3 of Experiment 3, C16/C17 of Experiment 4):
supervised Kohonen maps (eq. 6.7-6.8, 6.14-6.16) and the order in which they see the training
images."""
from __future__ import annotations

from typing import Sequence

import torch

from ..nn import SOM
from .params import PostureMapParams


def posture_maps(init_high: float, q: PostureMapParams, n_in: int, units: int, generators,
                 names: Sequence[str]) -> list[SOM]:
    """The chapter-6 image -> wrist-posture maps (supervised Kohonen, eq. 6.7-6.8), one per name,
    built in order, initial weights U[0, ``init_high``], the schedule of ``q``."""
    kw = dict(shape=(units,), n_in=n_in, generators=generators, init=(0.0, init_high), eta=q.eta,
              sigma=q.sigma, eta_final=q.eta_final, sigma_final=q.sigma,
              iterations=q.iterations, supervised=True, readout="dot", input_scale="sum")
    return [SOM(name=name, **kw) for name in names]


def posture_order(generators, n: int, steps: int) -> torch.Tensor:
    """Image indices ``(P, steps)`` for the posture maps: every one of the ``n`` images once per pass,
    a fresh random order per pass and participant."""
    passes = -(-steps // n)
    return torch.stack([torch.cat([torch.randperm(n, generator=g) for _ in range(passes)])[:steps] for g in generators])


def fit_posture_soms(soms, maps: torch.Tensor, labels: torch.Tensor, generators, progress=None) -> None:
    """Train each supervised posture map of ``soms`` on ``maps`` labelled ``labels``, in passes over
    the images (:func:`posture_order`), by the factored form of the online rule."""
    for som in (progress(soms) if progress is not None else soms):
        order = posture_order(generators, maps.shape[0], som.rule.iterations)
        som.fit(maps, labels=labels, generators=None, order=order, method="factored")
