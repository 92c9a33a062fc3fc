"""Decision dynamics: a dynamic neural field competing to threshold (thesis 5.1-5.2), a leaky
competing accumulator (eq. 6.12-6.13) and softmax selection (eq. 6.3, 6.11, 7.7).

One cycle of either dynamics is one simulated millisecond of response time (thesis chapter 5).
Both compute on their input's device and in its dtype. A race stops once every element has
decided; on the ``meta`` device, where there are no values to look at, it runs all its cycles.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import torch
from torch import nn

from .functional import check_floating, check_tensor, grid_coords, softmax_probabilities, softmax_select
from .limits import FIELD_BOUNDS, LCA_BOUNDS, check_bounds


@dataclass
class Decision:
    """Result of a race to threshold for a batch ``(P, B)``.

    ``winner``: index of the first unit to cross (long; -1 if none did); ``cycles``: cycles until
    it crossed (``max_cycles`` if none did); ``decided``: whether any unit crossed; ``state``: the
    final activity.
    """

    winner: torch.Tensor
    cycles: torch.Tensor
    decided: torch.Tensor
    state: torch.Tensor


class DynamicField(nn.Module):
    """A neural field with all-to-all lateral weights inside one map.

    ``u <- u + (dt / tau) (-u + h + s + W f(u))`` with ``f(u) = clamp(u, 0, 1)`` and a lateral
    kernel ``W(d) = a_exc exp(-d^2 / (2 sigma_exc^2)) - a_inh`` of the grid distance ``d``:
    short-range excitation, long-range inhibition (Amari / Erlhagen & Schoener style). The field
    is iterated until a unit's activity crosses ``threshold``; the number of cycles is the
    simulated response time.

    Args:
        shape: map grid ``(n,)`` or ``(rows, cols)``.
        tau: time constant in cycles; dt is one cycle.
        h: resting level.
        a_exc, sigma_exc: amplitude and width (grid units) of the local excitation.
        a_inh: strength of the global inhibition between every pair of units.
        threshold: activity a unit must reach to win.
    """

    # bounds of the parameters (keyword arguments of nn.limits.check_rate); schemas check with these
    BOUNDS = FIELD_BOUNDS

    def __init__(self, shape: Sequence[int], tau: float = 10.0, h: float = 0.0, a_exc: float = 0.6,
                 sigma_exc: float = 1.5, a_inh: float = 0.15, threshold: float = 0.9, name: str = "") -> None:
        super().__init__()
        self.shape = tuple(int(s) for s in shape)
        ok = check_bounds(self.BOUNDS, dict(tau=tau, h=h, a_exc=a_exc, sigma_exc=sigma_exc, a_inh=a_inh,
                                            threshold=threshold))
        self.tau, self.h, self.a_exc = ok["tau"], ok["h"], ok["a_exc"]
        self.sigma_exc, self.a_inh, self.threshold = ok["sigma_exc"], ok["a_inh"], ok["threshold"]
        self.name = name or f"DynamicField({'x'.join(map(str, self.shape))})"
        g = grid_coords(self.shape)
        d2 = ((g.unsqueeze(0) - g.unsqueeze(1)) ** 2).sum(-1)
        self.register_buffer("kernel", self.a_exc * torch.exp(-d2 / (2 * self.sigma_exc**2)) - self.a_inh)
        self.n = g.shape[0]

    def step(self, u: torch.Tensor, s: torch.Tensor) -> torch.Tensor:
        """One Euler cycle for activity ``u`` and input ``s``, both ``(..., n)``."""
        f = u.clamp(0.0, 1.0)
        return u + (-u + self.h + s + f @ self.kernel.to(dtype=u.dtype).T) / self.tau

    @torch.no_grad()
    def forward(self, s: torch.Tensor, max_cycles: int = 1000, u0: torch.Tensor | None = None) -> Decision:
        """Race to threshold with constant input ``s`` ``(..., *shape)``; returns a :class:`Decision`."""
        check_tensor(f"input of DynamicField {self.name!r}", s, self.shape)
        check_floating(f"input of DynamicField {self.name!r}", s)
        if max_cycles < 1:
            raise ValueError(f"max_cycles must be >= 1, got {max_cycles}")
        flat = s.reshape(*s.shape[: s.dim() - len(self.shape)], self.n)
        u = torch.full_like(flat, self.h) if u0 is None else u0.reshape(flat.shape).clone()
        batch = flat.shape[:-1]
        winner = torch.full(batch, -1, dtype=torch.long, device=s.device)
        cycles = torch.full(batch, max_cycles, dtype=torch.long, device=s.device)
        done = torch.zeros(batch, dtype=torch.bool, device=s.device)
        early = s.device.type != "meta"  # stop once all decided (reads `done` on the host)
        for t in range(1, max_cycles + 1):
            u = self.step(u, flat)
            m, idx = u.max(-1)
            new = (m >= self.threshold) & ~done
            if not early:
                winner = torch.where(new, idx, winner)
                cycles = torch.where(new, torch.full_like(cycles, t), cycles)
                done = done | new
            elif new.any():
                winner = torch.where(new, idx, winner)
                cycles = torch.where(new, torch.full_like(cycles, t), cycles)
                done = done | new
                if bool(done.all()):
                    break
        return Decision(winner, cycles, done, u.reshape(s.shape))

    def reset_state(self) -> None:
        pass


class LeakyCompetingAccumulator(nn.Module):
    """Leaky competing accumulator (Usher & McClelland; eq. 6.12-6.13).

    For two (or more) options: ``dy_i = dt (-k y_i - w sum_{j != i} y_j + I_i)``, activities kept
    non-negative. The accumulator crossing ``threshold`` first gives the answer. The state can be
    carried over between calls, so a trial can feed it ``cycles`` cycles per rotation step without
    resetting (thesis: 10 cycles per step, threshold 1.2, w = 0.5).

    Args:
        k: leak (not given in the thesis; see docs/choices.md).
        w: mutual inhibition.
        threshold: decision threshold.
        dt: integration step per cycle.
        noise: amplitude of Gaussian noise per unit time (Euler-Maruyama): each cycle adds
            ``noise * randn / sqrt(dt)`` to ``dy_i`` before ``y_i += dt * dy_i``, so the noise added
            to an accumulator in one cycle has standard deviation ``noise * sqrt(dt)``
            (0 = deterministic).
    """

    BOUNDS = LCA_BOUNDS

    def __init__(self, n: int = 2, k: float = 0.2, w: float = 0.5, threshold: float = 1.2, dt: float = 0.1,
                 noise: float = 0.0, name: str = "") -> None:
        super().__init__()
        if n < 2:
            raise ValueError(f"n must be >= 2 options, got {n}")
        self.n = int(n)
        ok = check_bounds(self.BOUNDS, dict(k=k, w=w, threshold=threshold, dt=dt, noise=noise))
        self.k, self.w, self.threshold, self.dt, self.noise = (ok[n] for n in ("k", "w", "threshold", "dt", "noise"))
        self.name = name

    def initial_state(self, batch: Sequence[int], device: torch.device | str | None = None,
                      dtype: torch.dtype | None = None) -> torch.Tensor:
        """Silent accumulators ``(*batch, n)`` (default: float32 on the CPU, as ``torch.zeros``)."""
        return torch.zeros(*batch, self.n, device=device, dtype=dtype)

    @torch.no_grad()
    def forward(self, inputs: torch.Tensor, cycles: int, state: torch.Tensor | None = None,
                active: torch.Tensor | None = None, generator: torch.Generator | None = None,
                leak: torch.Tensor | None = None) -> Decision:
        """Integrate ``cycles`` cycles of ``inputs`` ``(..., n)``; stop each element at threshold.

        ``active`` (bool ``(...)``) freezes elements that already decided. ``leak`` ``(...)``, if
        given, is each element's own leak in place of ``k`` (accumulators calibrated one by one).
        ``Decision.cycles`` is the number of cycles this call ran for each element until it decided
        (``cycles`` if not).
        """
        check_tensor("inputs", inputs, (self.n,))
        if cycles < 1:
            raise ValueError(f"cycles must be >= 1, got {cycles}")
        dev = inputs.device
        like = inputs.dtype if inputs.is_floating_point() else None
        y = self.initial_state(inputs.shape[:-1], dev, like) if state is None else state.clone()
        k = self.k if leak is None else leak.to(device=dev, dtype=y.dtype).unsqueeze(-1)
        batch = inputs.shape[:-1]
        live = torch.ones(batch, dtype=torch.bool, device=dev) if active is None else active.clone()
        winner = torch.full(batch, -1, dtype=torch.long, device=dev)
        used = torch.full(batch, cycles, dtype=torch.long, device=dev)
        decided = torch.zeros(batch, dtype=torch.bool, device=dev)
        early = dev.type != "meta"  # stop once all decided (reads `live` on the host)
        neg_k = -k
        for t in range(1, cycles + 1):
            total = _total(y)
            dy = neg_k * y - self.w * (total - y) + inputs
            if self.noise > 0:  # drawn where the generator lives (default: y's device), in y's dtype
                g_dev = dev if generator is None else generator.device
                z = torch.randn(y.shape, generator=generator, device=g_dev, dtype=y.dtype).to(dev)
                dy = dy + self.noise * z / self.dt ** 0.5
            y = torch.where(live.unsqueeze(-1), (y + self.dt * dy).clamp_min(0.0), y)
            m, idx = _largest(y)
            new = live & (m >= self.threshold)
            if not early:
                winner = torch.where(new, idx, winner)
                used = torch.where(new, torch.full_like(used, t), used)
                decided = decided | new
                live = live & ~new
            elif new.any():
                winner = torch.where(new, idx, winner)
                used = torch.where(new, torch.full_like(used, t), used)
                decided |= new
                live = live & ~new
                if not bool(live.any()):
                    break
        return Decision(winner, used, decided, y)

    def reset_state(self) -> None:
        pass


def _total(y: torch.Tensor) -> torch.Tensor:
    """``y.sum(-1, keepdim=True)``; of two units their one addition (the same number: a sum of two
    floats rounds once however it is accumulated), without a reduction kernel."""
    return y[..., :1] + y[..., 1:] if y.shape[-1] == 2 else y.sum(-1, keepdim=True)


def _largest(y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``y.max(-1)``: the largest unit and its index (the first of equal ones); of two units by one
    comparison, without a reduction kernel."""
    if y.shape[-1] != 2:
        return y.max(-1)
    a, b = y[..., 0], y[..., 1]
    return torch.maximum(a, b), (b > a).long()


def full_match_gain(threshold: float, k: float, dt: float, cycles: int) -> float:
    """The smallest input gain with which evidence 1, alone from rest, carries a leaky accumulator
    (leak ``k``, Euler step ``dt``) across ``threshold`` within ``cycles`` cycles:
    ``threshold k / (1 - (1 - dt k)^cycles)`` (``threshold / (dt cycles)`` without leak)."""
    if k == 0:
        return threshold / (dt * cycles)
    return threshold * k / (1.0 - (1.0 - dt * k) ** cycles)


@torch.no_grad()
def smallest_deciding_gain(pmcd: "LeakyCompetingAccumulator", evidence: torch.Tensor, cycles: int,
                           answer: int | torch.Tensor = 0, iterations: int = 60,
                           leak: torch.Tensor | None = None) -> torch.Tensor:
    """The smallest gain ``g`` (per row of ``evidence`` ``(R, 2)``) with which the accumulator ``pmcd``,
    from rest, fed ``g * evidence`` crosses its threshold on unit ``answer`` within ``cycles`` cycles:
    bisection on ``g`` (the crossing is monotone in the gain), every row at once. ``answer``: one
    unit for every row, or each row's ``(R,)``; ``leak`` ``(R,)``: each row's leak in place of
    ``pmcd.k``. Rows whose evidence favours the other unit, or is empty, get ``inf``. Each row's
    gain depends on that row alone (the accumulator integrates every row by itself), so rows
    searched together get the gains they would get searched one by one."""
    R = evidence.shape[0]
    lo, hi = torch.zeros(R, dtype=torch.float64), torch.ones(R, dtype=torch.float64)
    ans = torch.as_tensor(answer, dtype=torch.long).expand(R)
    own = evidence.gather(1, ans.unsqueeze(1)).squeeze(1)
    ok = (own > evidence.gather(1, (1 - ans).unsqueeze(1)).squeeze(1)) & (own > 0)

    def decides(g):
        d = pmcd((g.unsqueeze(-1) * evidence.double()).float(), cycles, state=pmcd.initial_state((R,)), leak=leak)
        return d.decided & (d.winner == ans)

    for _ in range(40):  # grow the upper bound until it decides
        bad = ok & ~decides(hi)
        if not bool(bad.any()):
            break
        hi = torch.where(bad, hi * 2, hi)
    for _ in range(iterations):
        mid = (lo + hi) / 2
        d = decides(mid)
        hi, lo = torch.where(d, mid, hi), torch.where(d, lo, mid)
    hi = hi * (1 + 1e-5)  # clear of the float32 rounding of the evidence the trials compute
    return torch.where(ok, hi, torch.full_like(hi, float("inf"))).float()


__all__ = ["Decision", "DynamicField", "LeakyCompetingAccumulator", "smallest_deciding_gain", "softmax_select",
           "softmax_probabilities"]
