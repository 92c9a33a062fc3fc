"""The arm's movements in the tool-use world: DMP primitives (eq. 7.2-7.5) bounded by the joint
limits only, and the thesis's way of drawing them at random (docs/robot.md, goal noise rule).

A DMP starts with random goal and shape parameters (thesis: "all DMPs will be assigned with random
values to their shape and goal parameters"): goals uniform inside the URDF joint limits, shape
weights N(0, ``weight_sigma``). Exploration "adds noise to the goal parameters": Gaussian noise of
standard deviation ``WorldConfig.goal_noise_share`` times each joint's range, clipped to the limits.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from neuroimagery.motor.dmp import DMP


@dataclass(frozen=True)
class MovementConfig:
    """How random movements are drawn and how long one movement lasts."""

    weight_sigma: float = 300.0  # std of the random shape weights
    duration_s: float = 1.5  # movement duration (DMP time constant)
    dt: float = 0.02  # trajectory step (= WorldConfig.control_dt)

    def __post_init__(self) -> None:
        for key in ("weight_sigma", "duration_s", "dt"):
            if not getattr(self, key) > 0:
                raise ValueError(f"MovementConfig.{key} must be positive, got {getattr(self, key)}")


def world_dmp() -> DMP:
    """The DMP of this world's movements: no bound on the goal but the joint limits."""
    return DMP(max_goal_offset=None)


def random_primitives(world, dmp: DMP, n: int, cfg: MovementConfig, generator: torch.Generator) -> torch.Tensor:
    """``n`` freshly drawn DMPs: goals uniform inside the joint limits, weights N(0, weight_sigma)."""
    lim = world.kin.joint_limits.float()
    goals = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * torch.rand(n, 7, generator=generator)
    weights = cfg.weight_sigma * torch.randn(n, 7, dmp.n_basis, generator=generator)
    return dmp.pack(goals, weights)


def goal_noise(world, dmp: DMP, theta: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """``theta`` (N, P) with Gaussian noise of ``goal_noise_share`` x each joint's range added to its
    goals, clipped to the joint limits (the shape weights unchanged)."""
    lim = world.kin.joint_limits.float()
    g, w = dmp.split(theta)
    sigma = world.cfg.goal_noise_share * (lim[:, 1] - lim[:, 0])
    return dmp.pack(world.kin.clamp(g + sigma * torch.randn(g.shape, generator=generator)), w)


def explore(world, dmp: DMP, theta: torch.Tensor, q0: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Exploratory movements (Fig. 7.5 A) of the DMPs ``theta`` (N, P) from the initial posture
    ``q0``: each DMP is reinitialised with the posture, its goal set to ``q0``, then the goal noise
    is added (Fig. 7.5, section 7.1.2; docs/contracts.md, W9). Shape weights unchanged."""
    g, w = dmp.split(theta)
    theta = dmp.pack(q0.to(g.dtype).expand_as(g).clone(), w)
    return goal_noise(world, dmp, theta, generator)


def trajectories(world, dmp: DMP, theta: torch.Tensor, q0: torch.Tensor, cfg: MovementConfig) -> torch.Tensor:
    """DMP rollouts (N, T, 7) from joint vector ``q0``, clipped to the URDF joint limits."""
    return world.kin.clamp(dmp.rollout(theta if theta.dim() == 2 else theta[None], q0, cfg.duration_s, cfg.dt))
