"""Policy improvement with black-box optimisation, PI^BB (thesis eq. 7.6-7.8).

One iteration, in the numbered steps of the thesis:

1. adding noise   theta_k = M_i + eps_k,  eps_k ~ N(0, Sigma_i),  k = 1..K          (eq. 7.6)
2. awarding       J_k = cost of rolling out theta_k (computed elsewhere: a cost function reads a
                  rollout's outcome; the simulator that performed it is not involved)
3. weighting      p_k = exp(-J_k / temperature) / sum_l exp(-J_l / temperature)      (eq. 7.7)
4. averaging      M_{i+1} = sum_k p_k theta_k                                         (eq. 7.8)

and the exploration covariance shrinks by ``decay`` each update.  When every sample cost the same
the weights are uniform and step 4 is the plain mean of the samples (eq. 7.8 as printed).
``PIBB`` is immutable:
``update`` returns a new distribution and leaves the old one as it was.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import torch


@dataclass(frozen=True)
class PIBB:
    """Search distribution N(mean, covariance) over flat policy parameters.

    n_samples: K, samples per update (thesis: 10).
    temperature: tau of eq. 7.7 (smaller = greedier averaging).
    decay: factor applied to the covariance after each update (1 = fixed exploration).
    """

    mean: torch.Tensor
    covariance: torch.Tensor
    n_samples: int = 10
    temperature: float = 0.1
    decay: float = 0.9

    def __post_init__(self) -> None:
        m, C = self.mean, self.covariance
        if m.dim() != 1:
            raise ValueError(f"PIBB mean must be a vector, got shape {tuple(m.shape)}")
        if C.shape != (len(m), len(m)):
            raise ValueError(f"PIBB covariance must be ({len(m)}, {len(m)}), got {tuple(C.shape)}")
        if not torch.isfinite(m).all():
            raise ValueError("PIBB mean contains NaN or inf")
        if not torch.isfinite(C).all():
            raise ValueError("PIBB covariance contains NaN or inf")
        if self.n_samples < 2:
            raise ValueError(f"PIBB n_samples must be >= 2, got {self.n_samples}")
        if not self.temperature > 0:
            raise ValueError(f"PIBB temperature must be > 0, got {self.temperature}")
        if not 0 < self.decay <= 1:
            raise ValueError(f"PIBB decay must be in (0, 1], got {self.decay}")

    @classmethod
    def from_sigma(cls, mean: torch.Tensor, sigma: torch.Tensor | float, **kw) -> "PIBB":
        """Diagonal covariance with standard deviations ``sigma`` (scalar or one per parameter)."""
        mean = torch.as_tensor(mean, dtype=torch.float32)
        sigma = torch.as_tensor(sigma, dtype=mean.dtype).expand_as(mean)
        return cls(mean.clone(), torch.diag(sigma**2), **kw)

    def sample(self, generator: torch.Generator | None = None) -> torch.Tensor:
        """K parameter vectors (K, D) drawn around the mean (eq. 7.6)."""
        L = torch.linalg.cholesky(self.covariance + 1e-12 * torch.eye(len(self.mean), dtype=self.mean.dtype))
        eps = torch.randn(self.n_samples, len(self.mean), generator=generator, dtype=self.mean.dtype)
        return self.mean + eps @ L.T

    def weights(self, costs: torch.Tensor) -> torch.Tensor:
        """Softmax weights of eq. 7.7 (shift-invariant, so costs are offset by their minimum)."""
        costs = torch.as_tensor(costs, dtype=self.mean.dtype)
        if costs.dim() != 1:
            raise ValueError(f"costs must be a vector, got shape {tuple(costs.shape)}")
        if not torch.isfinite(costs).all():
            raise ValueError("costs contain NaN or inf")
        return torch.softmax(-(costs - costs.min()) / self.temperature, dim=0)

    def update(self, samples: torch.Tensor, costs: torch.Tensor) -> "PIBB":
        """New distribution: probability-weighted mean of the samples (eq. 7.8), decayed covariance
        (all costs equal: the plain mean of the samples)."""
        if samples.dim() != 2 or samples.shape[1] != len(self.mean):
            raise ValueError(f"samples must be (K, {len(self.mean)}), got {tuple(samples.shape)}")
        if len(costs) != len(samples):
            raise ValueError(f"{len(samples)} samples but {len(costs)} costs")
        if not torch.isfinite(samples).all():
            raise ValueError("samples contain NaN or inf")
        p = self.weights(costs)
        return replace(self, mean=p @ samples.to(self.mean.dtype), covariance=self.covariance * self.decay)


def event_costs(outcomes, event: str) -> torch.Tensor:
    """Cost of each rollout for learning ``event``: 0 if it fired, 1 otherwise (thesis: reward 1/0).

    ``outcomes`` are objects with a ``fired(name)`` method (e.g. robot.world.Outcome); a rollout
    whose physics blew up costs 1.
    """
    return torch.tensor([0.0 if (o.fired(event) and not o.blew_up) else 1.0 for o in outcomes])


def graded_costs(outcomes, event: str, move_threshold: float = 0.02, retrieve_distance: float = 0.08,
                 reach: float = 0.10) -> torch.Tensor:
    """Cost in [0, 1] that also ranks the rollouts that missed the event (gives PI^BB a slope).

    0 when the event fired.  Otherwise ``1 - 0.6 * progress - 0.3 * closeness``, where
    ``progress`` in [0, 1] is how far the toy went the wanted way (displacement along the event's
    direction over ``move_threshold``; for "retrieve" the southward displacement over
    ``retrieve_distance``; 0 for "touch") and ``closeness`` in [0, 1] is ``1 - min_gap / reach``
    (``min_gap``: the closest the rake came to the toy, if the outcome reports it).  A blown-up
    rollout costs 1.
    """
    direction = {"south": (-1.0, 0.0), "north": (1.0, 0.0), "west": (0.0, 1.0), "east": (0.0, -1.0),
                 "retrieve": (-1.0, 0.0), "touch": (0.0, 0.0)}
    if event not in direction:
        raise ValueError(f"unknown event {event!r}")
    ux, uy = direction[event]
    scale = retrieve_distance if event == "retrieve" else move_threshold
    costs = []
    for o in outcomes:
        if o.blew_up:
            costs.append(1.0)
            continue
        if o.fired(event):
            costs.append(0.0)
            continue
        dx, dy = o.toy_displacement
        progress = min(max((ux * dx + uy * dy) / scale, 0.0), 1.0)
        gap = getattr(o, "min_gap", float("nan"))
        closeness = 0.0 if gap != gap else 1.0 - min(max(gap / reach, 0.0), 1.0)
        costs.append(1.0 - 0.6 * progress - 0.3 * closeness)
    return torch.tensor(costs)
