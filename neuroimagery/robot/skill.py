"""Learning one skill with PI^BB on the tool-use world (the B. Learning loop of thesis Fig. 7.5).

One update = one epoch of Fig. 7.5: from each of the 4 postures, K samples of the DMP's
parameters are rolled out (their goals bounded to ``WorldConfig.max_goal_offset_rad`` around that
posture, as in babbling) while the skill's event is watched, the cost of every rollout is read
from its outcome, and one PI^BB update uses all 4K samples. :func:`learn` scores rollouts with
``motor.pibb.graded_costs`` by default (``cost="graded"``: 0 when the event fired; a miss costs
between 0.1 and 1, less the further the toy went the wanted way and the closer the rake came to
it) or, with ``cost="binary"``, ``motor.pibb.event_costs`` (0 when the event fired, 1 otherwise).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from neuroimagery.motor.pibb import PIBB, event_costs, graded_costs
from neuroimagery.robot.babble import BabbleConfig, random_thetas, trajectories, world_dmp
from neuroimagery.robot.world import ToolWorld, event_index


@dataclass
class SkillCurve:
    theta: torch.Tensor  # final mean parameters (35,)
    sample_success: list[float]  # share of the 4K exploration rollouts that fired the event, per update
    mean_success: list[float]  # share of the 4 postures where the mean DMP fires the event (index 0 = before learning)


def discover(world: ToolWorld, event: str, posture: int, generator: torch.Generator, max_tries: int = 2000,
             cfg: BabbleConfig | None = None) -> torch.Tensor:
    """Babble from ``posture`` until a random DMP fires ``event``; return its parameters (35,)."""
    event_index(event)
    cfg, dmp = cfg or BabbleConfig(), world_dmp(world)
    for _ in range(0, max_tries, 20):
        theta = random_thetas(world, dmp, posture, 20, cfg, generator)
        outs = world.rollout(trajectories(world, dmp, theta, posture, cfg), posture, event)
        for th, o in zip(theta, outs):
            if o.fired(event) and not o.blew_up:
                return th
    raise RuntimeError(f"no random DMP fired {event!r} from posture {posture} in {max_tries} tries")


def mean_success(world: ToolWorld, theta: torch.Tensor, event: str, cfg: BabbleConfig) -> float:
    dmp = world_dmp(world)
    hits = [world.rollout(trajectories(world, dmp, theta[None], k, cfg), k, event)[0] for k in range(1, 5)]
    return float(sum(o.fired(event) and not o.blew_up for o in hits)) / 4


def learn(world: ToolWorld, theta0: torch.Tensor, event: str, n_updates: int = 10, generator=None,
          goal_sigma: float = 0.1, weight_sigma: float = 60.0, temperature: float = 0.1, decay: float = 0.9,
          cfg: BabbleConfig | None = None, cost: str = "graded") -> SkillCurve:
    """PI^BB on a DMP's 35 parameters (eq. 7.6-7.8).

    ``cost="binary"``: 0 when the skill's event fired, else 1 (the thesis's reward only);
    ``cost="graded"`` (default): :func:`~neuroimagery.motor.pibb.graded_costs`, which also ranks the
    misses by how far the toy went the wanted way and how close the rake came to it.
    """
    if cost not in ("binary", "graded"):
        raise ValueError(f"cost must be 'binary' or 'graded', got {cost!r}")
    cfg, dmp = cfg or BabbleConfig(), world_dmp(world)
    sigma = torch.cat([torch.full((7,), goal_sigma), torch.full((28,), weight_sigma)])
    dist = PIBB.from_sigma(theta0, sigma, n_samples=10, temperature=temperature, decay=decay)
    sample_curve, mean_curve = [], [mean_success(world, dist.mean, event, cfg)]
    lo, hi = world.kin.joint_limits[:, 0], world.kin.joint_limits[:, 1]
    for _ in range(n_updates):
        samples, costs = [], []
        for k in range(1, 5):  # 1. adding noise, 2. awarding
            s = dist.sample(generator)
            s[:, :7] = torch.maximum(torch.minimum(s[:, :7], hi), lo)
            outs = world.rollout(trajectories(world, dmp, s, k, cfg), k, event)
            samples.append(s)
            if cost == "binary":
                costs.append(event_costs(outs, event))
            else:
                costs.append(graded_costs(outs, event, world.cfg.move_threshold,
                                          world.cfg.toy_xy[0] - world.cfg.retrieve_x))
        samples, costs = torch.cat(samples), torch.cat(costs)
        sample_curve.append(float((costs == 0).float().mean()))
        big = PIBB(dist.mean, dist.covariance, n_samples=len(samples), temperature=temperature, decay=decay)
        dist = big.update(samples, costs)  # 3. weighting, 4. averaging
        dist = PIBB(dist.mean, dist.covariance, n_samples=10, temperature=temperature, decay=decay)
        mean_curve.append(mean_success(world, dist.mean, event, cfg))
    return SkillCurve(dist.mean, sample_curve, mean_curve)
