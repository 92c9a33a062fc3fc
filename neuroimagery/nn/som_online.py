"""The online Kohonen step (eq. 4.5) with every unit's weights updated at every presentation,
as a fast kernel (``SOM.fit(method='online')``).

The arithmetic per presentation ``t`` is that of :meth:`SOM.step` with :class:`~.rules.Kohonen`:
winner ``c = argmin_k |x_t - w_k|^2``, then ``w_k <- w_k + h_k (x_t - w_k)`` for all units with
``h_k = eta(t) theta_k(t)``. What differs is how the numbers are obtained:

* **One pass over the weights per presentation.** The update is one fused in-place
  ``lerp_`` of the ``(P, units, in)`` weights (no temporary the size of the weights).
* **Distances without a pass of their own.** Steps run in chunks of ``chunk`` presentations whose
  patterns are known in advance (the order is drawn before training). At the start of a chunk one
  matrix product gives ``w_k . x_j`` for every pattern ``x_j`` of the chunk, and the squared norms
  ``|w_k|^2`` are recomputed. Within the chunk both follow the update exactly, in float64:
  ``w_k' . x_j = (1 - h_k) w_k . x_j + h_k x_t . x_j`` and
  ``|w_k'|^2 = (1 - h_k)^2 |w_k|^2 + 2 h_k (1 - h_k) w_k . x_t + h_k^2 |x_t|^2``. The drift of these
  recurrences is bounded by the refresh at every chunk.
* **Separable neighbourhood.** On a grid, ``exp(-(dr^2 + dc^2) / 2 sigma^2)`` is the outer product
  of two 1-D Gaussians (exact up to float rounding); the rule's cutoff (``theta < cutoff -> 0``) is
  applied to the product as the rule does.
* **Units with a zero rate are skipped.** ``lerp`` with weight 0 leaves a weight unchanged, so
  only the contiguous span of units with ``h_k > 0`` (for any participant) is passed over; with
  ``cutoff = 0`` and a wide neighbourhood that span is the whole map.

Supervised maps (forced winners, :class:`~.rules.SupervisedKohonen`) normalise every updated unit
to unit sum: the row sums follow the update in closed form, the rows are rescaled in the same
step, and the maintained dot products and norms are rescaled with them.

``truncate`` (a named option, not the default, not the reference rule): the Gaussian is set to 0
beyond ``truncate * sigma`` grid units of the winner along either axis, so a step passes over a
band of grid rows instead of the whole map. It changes the result (the tails of the Gaussian are
dropped); ``benchmarks/bench_blocks.py`` measures it apart.

The tests compare winners and weights with the plain step (``tests/test_som_online.py``).
"""
from __future__ import annotations

import torch

from .forms import Form, register
from .rules import Kohonen, Rule, SupervisedKohonen
from .som import SOM, curve, fit_plain

CHUNK = 32  # presentations per refresh of the dot products and norms
ROWSUM_FLOOR = 1e-12  # smallest row sum a normalised unit is divided by (dimensionless)
F64 = torch.float64  # the precision of the maintained dot products and norms


def supports(rule) -> bool:
    """Whether ``rule`` is the (supervised) Kohonen step this kernel implements (a subclass that
    changes the step, neighbourhood or schedule is trained with its own ``delta``)."""
    cls = type(rule)
    base = SupervisedKohonen if isinstance(rule, SupervisedKohonen) else Kohonen
    return (isinstance(rule, Kohonen) and cls.delta is base.delta and cls.neighbourhood is Kohonen.neighbourhood
            and cls.schedule is Kohonen.schedule)


def _axis_gaussians(shape, win: torch.Tensor, sigma: torch.Tensor, axes, truncate: float | None):
    """``theta`` ``(P, units)`` as the outer product of one 1-D Gaussian per grid axis."""
    den = 2.0 * sigma**2
    theta = None
    rest = win
    coords = []
    for n in reversed(shape):  # unit index is row-major: the last axis varies fastest
        coords.append(rest % n)
        rest = rest // n
    coords.reverse()
    for ax, c in zip(axes, coords):
        d = ax - c.to(ax.dtype).unsqueeze(-1)  # (P, n_axis)
        g = torch.exp(-(d * d) / den)
        if truncate is not None:
            g = torch.where(d.abs() > truncate * sigma, torch.zeros_like(g), g)
        theta = g if theta is None else (theta.unsqueeze(-1) * g.unsqueeze(1)).flatten(1)
    return theta


@torch.no_grad()
def fit_online(som, X: torch.Tensor, order: torch.Tensor, labels: torch.Tensor | None = None, steps=None,
               truncate: float | None = None, chunk: int = CHUNK, fold: bool = True) -> torch.Tensor:
    """Online training of ``som`` on patterns ``X`` ``(P, N, in)`` in the given ``order`` ``(P, T)``;
    ``labels`` ``(P, N)`` force the winners (supervised maps). ``steps`` optionally iterates over
    ``range(T)`` (a progress bar). ``fold=False`` applies each presentation's update to the weights
    as it happens (one ``lerp_``); ``fold=True`` applies the ``chunk`` updates of a chunk at its
    end as their exact composition. Returns the winners ``(P, T)`` and advances ``som.steps``.
    """
    if truncate is not None and not truncate > 0:
        raise ValueError(f"truncate must be > 0 grid sigmas, got {truncate}")
    if int(chunk) < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    run = _OnlineRun(som, X, order, labels, truncate, int(chunk), fold)
    for t in range(run.T) if steps is None else steps:
        run.step(t)
    som.steps += run.T
    return run.winners


class _OnlineRun:
    """The state of one :func:`fit_online` call: the schedule, the chunk's maintained dot products
    ``D`` ``(P, chunk, U)``, norms, pattern Gram matrix ``G`` (and row sums of a normalised map),
    and with ``fold`` the chunk's pending updates ``Hs``, ``Bs`` over the units ``span``."""

    def __init__(self, som, X, order, labels, truncate, chunk: int, fold: bool):
        rule, W = som.rule, som.weight
        P, U, _ = W.shape
        self.T = order.shape[1]
        dev, dt = W.device, W.dtype
        self.som, self.W, self.U, self.X, self.order, self.labels = som, W, U, X, order, labels
        self.truncate, self.chunk, self.fold = truncate, chunk, fold
        self.p = torch.arange(P, device=dev)
        t0 = int(som.steps)
        eta_all, sigma_all = rule.schedule(torch.arange(t0, t0 + self.T, device=dev))
        self.eta_all, self.sigma_all = eta_all.to(dt), sigma_all.to(dt)
        self.axes = [torch.arange(s, dtype=dt, device=dev) for s in som.shape]
        self.normalise = isinstance(rule, SupervisedKohonen) and rule.normalise
        self.cutoff = float(rule.cutoff)
        self.winners = torch.empty_like(order)
        self.watch = curve(som, self.T)
        if fold:
            self.Hs = torch.zeros(P, chunk, U, dtype=F64, device=dev)  # per step: rate toward x_t ...
            self.Bs = torch.ones(P, chunk, U, dtype=F64, device=dev)  # ... and factor on the weights
        self.span = [U, 0]  # units touched in the current chunk

    def step(self, t: int) -> None:
        """Presentation ``t``: its winner, the rates, the update of the moving units."""
        i = t % self.chunk
        if i == 0:
            self._refresh(t)
        dots = self.D[:, i]  # (P, U)
        xx = self.G[:, i, i].unsqueeze(-1)
        win = self._winner(t, dots, xx)
        h = self._rates(t, win)
        if self.normalise:  # the rule rescales every unit, moved or not
            lo, hi = 0, self.U
        else:
            on = (h > 0).any(0).nonzero()
            lo, hi = (int(on[0]), int(on[-1]) + 1) if on.numel() else (0, 0)  # (0, 0): nothing moves
        if hi > lo:
            self._update(i, h, lo, hi, dots, xx)
        if self.fold and (i == self.chunk - 1 or t == self.T - 1):
            _fold(self.W, self.Hs, self.Bs, self.Xc, i + 1, self.span)

    def _refresh(self, t: int) -> None:
        """At a chunk's start: dot products with the chunk's patterns, norms (and row sums)."""
        W = self.W
        idx = self.order[:, t:t + self.chunk]
        self.Xc = self.X[self.p.unsqueeze(-1), idx]  # (P, K, in)
        self.D = torch.bmm(self.Xc, W.transpose(1, 2)).to(F64)  # (P, K, U)  w_k . x_j, pattern-major
        self.nrm = torch.linalg.vector_norm(W, dim=-1).to(F64).square_()  # (P, U)
        Xd = self.Xc.to(F64)
        self.G = torch.bmm(Xd, Xd.transpose(1, 2))  # (P, K, K)
        if self.normalise:
            self.rowsum = W.sum(-1).to(F64)
            self.xsum = Xd.sum(-1)  # (P, K)
        self.span = [self.U, 0]

    def _winner(self, t: int, dots, xx) -> torch.Tensor:
        """The winner of presentation ``t`` (nearest unit, or the label), recorded with the curve."""
        if self.labels is None:
            win = (self.nrm - 2 * dots + xx).clamp_min_(0).argmin(-1)
        else:
            win = self.labels[self.p, self.order[:, t]]
        self.winners[:, t] = win
        if self.watch is not None:  # the training curve: |w_win - x_t| before the step
            self.watch.add(t, (self.nrm - 2 * dots + xx).gather(-1, win.unsqueeze(-1)).clamp_min(0).sqrt().mean())
        return win

    def _rates(self, t: int, win) -> torch.Tensor:
        """``h`` ``(P, U)``: the rate of every unit toward pattern ``t`` (the cut neighbourhood)."""
        theta = _axis_gaussians(self.som.shape, win, self.sigma_all[t], self.axes, self.truncate)
        if self.cutoff > 0:
            theta = torch.where(theta < self.cutoff, torch.zeros_like(theta), theta)
        return self.eta_all[t] * theta

    def _update(self, i: int, h, lo: int, hi: int, dots, xx) -> None:
        """Step ``i`` of the chunk on units ``lo:hi``: norms and later dot products in closed form,
        the weights now (``fold=False``) or the pending update recorded."""
        self.span[0], self.span[1] = min(self.span[0], lo), max(self.span[1], hi)
        nrm, hs = self.nrm, h[:, lo:hi]
        a = hs.to(F64)
        b = 1 - a
        nrm[:, lo:hi] = b * b * nrm[:, lo:hi] + 2 * a * b * dots[:, lo:hi] + a * a * xx
        rest = self.D[:, i + 1:, lo:hi]  # the chunk's later patterns
        rest.mul_(b.unsqueeze(1)).addcmul_(self.G[:, i, i + 1:].unsqueeze(-1), a.unsqueeze(1))
        if self.normalise:
            k = 1.0 / (b * self.rowsum + a * self.xsum[:, i].unsqueeze(-1)).clamp_min_(ROWSUM_FLOOR)
            nrm.mul_(k * k)
            rest.mul_(k.unsqueeze(1))
            self.rowsum.fill_(1.0)
            a, b = a * k, b * k
        if self.fold:
            self.Hs[:, i, lo:hi] = a
            self.Bs[:, i, lo:hi] = b
        else:
            self.W[:, lo:hi].lerp_(self.Xc[:, i].unsqueeze(1), hs.unsqueeze(-1))
            if self.normalise:
                self.W.mul_(k.to(self.W.dtype).unsqueeze(-1))


def _fold(W, Hs, Bs, Xc, K, span) -> None:
    """At the end of a chunk of ``K`` presentations, apply the composition of their updates
    ``w <- B_s w + H_s x_s`` to units ``span``: ``w <- (prod_s B_s) w + sum_s H_s (prod_{r > s} B_r) x_s``."""
    lo, hi = span
    if hi > lo:
        S = Bs[:, :K, lo:hi].flip(1).cumprod(1).flip(1)  # S[s] = prod_{r >= s} B_r
        C = Hs[:, :K, lo:hi].clone()
        C[:, :K - 1] *= S[:, 1:]
        dt = W.dtype
        W[:, lo:hi].mul_(S[:, 0].to(dt).unsqueeze(-1)).baddbmm_(C.transpose(1, 2).to(dt), Xc[:, :K])
    Hs.zero_()
    Bs.fill_(1.0)


@register(Rule, SOM)
class Online(Form):
    """``method='online'``: every unit updated at every presentation: :func:`fit_online` for the
    Kohonen rules, :func:`~.som.fit_plain` (one :meth:`SOM.step` per step, the plain rule, on any
    device and dtype) for any other. 'auto' takes it when no faster form applies."""

    name, priority = "online", 99

    def run(self, som, rule, call) -> torch.Tensor:
        if som.weight.device.type != "meta" and supports(rule):
            return fit_online(som, call.X, call.order, call.labels, call.steps)
        return fit_plain(som, call.X, call.order, call.labels, call.steps)
