"""Dynamic movement primitives for the iCub's right arm (thesis eq. 7.2-7.5), batched in torch.

For every joint j, with the movement's duration ``tau`` as time constant:

    tau^2 * y''  = alpha_v * (beta_v * (g - y) - tau * y') + f(x, g)           (eq. 7.2)
    f(x, g)      = sum_i(psi_i(x) * w_i) / sum_i(psi_i(x)) * x * (g - y0)      (eq. 7.3)
    psi_i(x)     = exp(-h_i * (x - c_i)^2)                                     (eq. 7.4)
    tau * x'     = -alpha_x * x,   x(0) = 1                                     (eq. 7.5)

Parameter layout (one flat vector per rollout, ``theta`` of shape (N, n_joints * (1 + n_basis))):
    theta[:, :n_joints]                      the goals g (rad, absolute joint angles)
    theta[:, n_joints + j*n_basis + i]        weight w_i of joint j (i = 0..n_basis-1)
With the thesis's 7 joints and 4 basis functions: 7 goals then 28 shape weights = 35 numbers.

Goals are absolute joint angles, so one DMP rolled out from different initial postures ends in the
same arm configuration by different paths, as long as that configuration lies within the DMP's
reach: a movement starts from the arm's current posture and its goal is bounded to
``y0 +- max_goal_offset`` per joint (``MAX_GOAL_OFFSET_RAD`` by default; ``None`` removes the
bound).  The forcing term scales with ``g - y0`` (eq. 7.3), so the bound also shrinks the shape
term, but it does not cap the path: with large shape weights a joint can pass 2-4 times the bound
on the way to the goal.  Integration is semi-implicit Euler on the whole batch
at once; the phase ``x`` is evaluated in closed form.
"""
from __future__ import annotations

import math

import torch

from ..nn.functional import checks_enabled
from . import dmp_kernel

# Largest joint displacement (rad) of a movement's goal from its start posture: a skill is a
# movement from where the arm is, not a jump to anywhere in the joint range (docs/robot.md).
MAX_GOAL_OFFSET_RAD = 0.15


class DMP(torch.nn.Module):
    """A batch of DMPs, one per row of ``theta`` (eq. 7.2-7.5).

    alpha_v, beta_v: spring-damper gains of eq. 7.2 (``beta_v = alpha_v / 4`` is critical damping).
    alpha_x: decay of the canonical system, eq. 7.5 (``x(tau) = exp(-alpha_x)``).
    The basis centres ``c_i`` are spread evenly in time (so ``c_i = exp(-alpha_x * i / (n-1))``)
    and the widths are ``h_i = 2 ln 2 / (c_i - c_{i+1})^2`` (the last reuses the last gap): each
    Gaussian has fallen to ``exp(-ln2 / 2) ~ 0.71`` halfway to the next centre. Since the gaps
    differ, neighbours cross lower where the widths differ (defaults: at 0.42, 0.42 and 0.71).
    max_goal_offset: goals farther than this (rad, per joint) from the start ``y0`` are moved to
    ``y0 +- max_goal_offset`` before integrating; ``None`` leaves them unbounded.
    """

    def __init__(
        self,
        n_joints: int = 7,
        n_basis: int = 4,
        alpha_v: float = 25.0,
        beta_v: float = 6.25,
        alpha_x: float = 4.0,
        max_goal_offset: float | None = MAX_GOAL_OFFSET_RAD,
    ) -> None:
        super().__init__()
        if n_joints < 1 or n_basis < 1:
            raise ValueError(f"n_joints and n_basis must be >= 1, got {n_joints}, {n_basis}")
        for name, v in (("alpha_v", alpha_v), ("beta_v", beta_v), ("alpha_x", alpha_x)):
            if not v > 0:
                raise ValueError(f"DMP {name} must be > 0, got {v}")
        if max_goal_offset is not None and not (math.isfinite(max_goal_offset) and max_goal_offset > 0):
            raise ValueError(f"DMP max_goal_offset must be > 0 or None, got {max_goal_offset}")
        self.max_goal_offset = None if max_goal_offset is None else float(max_goal_offset)
        self.n_joints, self.n_basis = n_joints, n_basis
        self.alpha_v, self.beta_v, self.alpha_x = float(alpha_v), float(beta_v), float(alpha_x)
        self.compiled = True  # float32 CPU rollouts integrate in the compiled loop (motor.dmp_kernel): same bits
        t = torch.linspace(0.0, 1.0, n_basis, dtype=torch.float64)
        centres = torch.exp(-alpha_x * t)
        if n_basis > 1:
            gaps = (centres[:-1] - centres[1:]).abs()
            gaps = torch.cat([gaps, gaps[-1:]])
            widths = (2.0 * math.log(2.0)) / gaps**2  # exp(-ln2 / 2) ~ 0.71 halfway to the next centre
        else:
            widths = torch.ones(1, dtype=torch.float64)
        self.register_buffer("centres", centres.float())
        self.register_buffer("widths", widths.float())

    @property
    def n_params(self) -> int:
        return self.n_joints * (1 + self.n_basis)

    def split(self, theta: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, D) -> goals (N, J) and weights (N, J, B)."""
        J, B = self.n_joints, self.n_basis
        return theta[:, :J], theta[:, J:].reshape(-1, J, B)

    def pack(self, goals: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
        """goals (N, J) and weights (N, J, B) -> theta (N, D)."""
        return torch.cat([goals, weights.reshape(len(goals), -1)], dim=1)

    def _check(self, theta: torch.Tensor, y0: torch.Tensor, duration_s: float, dt: float):
        if theta.dim() == 1:
            theta = theta.unsqueeze(0)
        if theta.dim() != 2 or theta.shape[1] != self.n_params:
            raise ValueError(f"theta must have shape (N, {self.n_params}), got {tuple(theta.shape)}")
        if checks_enabled(theta) and not torch.isfinite(theta).all():
            raise ValueError("DMP parameters theta contain NaN or inf")
        y0 = torch.as_tensor(y0, dtype=theta.dtype, device=theta.device)
        if y0.dim() == 1:
            y0 = y0.expand(len(theta), -1)
        if y0.shape != (len(theta), self.n_joints):
            raise ValueError(f"y0 must have shape ({len(theta)}, {self.n_joints}) or ({self.n_joints},)")
        if checks_enabled(y0) and not torch.isfinite(y0).all():
            raise ValueError("DMP start y0 contains NaN or inf")
        if not (duration_s > 0 and dt > 0 and dt <= duration_s):
            raise ValueError(f"need 0 < dt <= duration_s, got dt={dt}, duration_s={duration_s}")
        return theta, y0

    def phase(self, t: torch.Tensor, duration_s: float) -> torch.Tensor:
        """Canonical variable x(t) = exp(-alpha_x t / tau), the solution of eq. 7.5."""
        return torch.exp(-self.alpha_x * t / duration_s)

    def forcing(self, x: torch.Tensor, weights: torch.Tensor, g: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        """Eq. 7.3-7.4 at phase ``x`` (scalar tensor): (N, J)."""
        psi = torch.exp(-self.widths * (x - self.centres) ** 2)  # (B,)
        shape = (weights * psi).sum(-1) / psi.sum()
        return shape * x * (g - y0)

    def bounded_goals(self, g: torch.Tensor, y0: torch.Tensor) -> torch.Tensor:
        """Goals moved into ``y0 +- max_goal_offset`` (unchanged when the bound is ``None``)."""
        if self.max_goal_offset is None:
            return g
        b = self.max_goal_offset
        return y0 + (g - y0).clamp(-b, b)

    def rollout(
        self, theta: torch.Tensor, y0: torch.Tensor, duration_s: float = 2.0, dt: float = 0.01
    ) -> torch.Tensor:
        """Integrate eq. 7.2 for every row of ``theta``: joint trajectories (N, T, J).

        ``T = round(duration_s / dt) + 1``; row 0 is ``y0`` (start at rest).  Goals are first
        bounded to ``y0 +- max_goal_offset`` (:meth:`bounded_goals`).
        """
        theta, y0 = self._check(theta, y0, duration_s, dt)
        g, w = self.split(theta)
        g = self.bounded_goals(g, y0)
        tau = float(duration_s)
        steps = int(round(duration_s / dt))
        y, v = y0.clone(), torch.zeros_like(y0)  # v = dy/dt
        out = theta.new_empty(len(theta), steps + 1, self.n_joints)
        out[:, 0] = y
        k, c = self.alpha_v * self.beta_v / tau**2, self.alpha_v / tau
        ts = torch.arange(steps, dtype=theta.dtype, device=theta.device) * dt
        xs = self.phase(ts, tau)
        psi = torch.exp(-self.widths.to(theta.dtype) * (xs[:, None] - self.centres.to(theta.dtype)) ** 2)  # (S, B)
        shape = torch.einsum("sb,njb->snj", psi / psi.sum(-1, keepdim=True), w)  # (S, N, J)
        f = shape * (xs[:, None, None] * (g - y0)) / tau**2
        if self.compiled and dmp_kernel.available(g, y0, f):
            return dmp_kernel.integrate(g, y0.expand_as(g), f, k, c, dt, out)
        for s in range(steps):
            acc = k * (g - y) - c * v + f[s]
            v = v + dt * acc
            y = y + dt * v
            out[:, s + 1] = y
        return out

    def analytical_solution(
        self, goal: torch.Tensor, y0: torch.Tensor, duration_s: float, dt: float, v0: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Closed-form solution of eq. 7.2 with ``f = 0`` (the spring-damper alone): (N, T, J).

        ``tau^2 y'' + alpha_v tau y' + alpha_v beta_v (y - g) = 0`` has characteristic roots
        ``r = (-a +- sqrt(a^2 - 4b)) / 2`` with ``a = alpha_v / tau``, ``b = alpha_v beta_v / tau^2``.
        """
        goal = torch.as_tensor(goal, dtype=torch.float64)
        y0 = torch.as_tensor(y0, dtype=torch.float64).expand_as(goal)
        v0 = torch.zeros_like(goal) if v0 is None else torch.as_tensor(v0, dtype=torch.float64).expand_as(goal)
        tau = float(duration_s)
        a, b = self.alpha_v / tau, self.alpha_v * self.beta_v / tau**2
        t = torch.arange(int(round(duration_s / dt)) + 1, dtype=torch.float64) * dt
        t = t.view(1, -1, 1)
        e0, de0 = (y0 - goal).unsqueeze(1), v0.unsqueeze(1)
        disc = a * a - 4 * b
        if abs(disc) < 1e-9 * a * a:  # critical damping
            r = -a / 2
            e = (e0 + (de0 - r * e0) * t) * torch.exp(r * t)
        elif disc > 0:
            r1, r2 = (-a + math.sqrt(disc)) / 2, (-a - math.sqrt(disc)) / 2
            B = (de0 - r1 * e0) / (r2 - r1)
            A = e0 - B
            e = A * torch.exp(r1 * t) + B * torch.exp(r2 * t)
        else:
            s, om = -a / 2, math.sqrt(-disc) / 2
            e = torch.exp(s * t) * (e0 * torch.cos(om * t) + (de0 - s * e0) / om * torch.sin(om * t))
        return goal.unsqueeze(1) + e
