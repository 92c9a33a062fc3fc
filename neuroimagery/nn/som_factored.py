"""The factored form of online Kohonen training (``SOM.fit(method='factored')``): the same
sequence of steps as the plain rule (eq. 4.5; supervised eq. 6.7-6.8), without touching the
weights while training.

Every weight vector stays a scaled combination ``w_k = c_k (w0_k + sum_n R_kn x_n)`` of its
initial value and the ``N`` training patterns, so the step ``w_k <- (1 - a_k) w_k + a_k x_s``
only rescales ``c_k`` and adds to ``R_ks``; distances come from maintained dot products with the
patterns and closed-form norms. A step costs ``(units in the neighbourhood) x N``, independent of
the input size, and the weights are formed once at the end. Same sequence of winners, same
weights up to float rounding (``tests/test_som.py`` checks both against the plain rule).
"""
from __future__ import annotations

import torch

from .forms import Form, register
from .rules import Kohonen, SupervisedKohonen
from .som import SOM, curve

FOLD_BELOW = 1e-12  # a unit's scale c_k below this is folded back into its factors (dimensionless)
ROWSUM_FLOOR = 1e-300  # smallest row sum a normalised unit is divided by (dimensionless)


@torch.no_grad()
def fit_factored(som, X: torch.Tensor, order: torch.Tensor, labels: torch.Tensor | None, it) -> torch.Tensor:
    """Train ``som`` on ``X`` ``(P, N, in)`` in the pattern ``order`` ``(P, T)`` (forced winners
    ``labels`` ``(P, N)`` or None), stepping through ``it``; returns the winners ``(P, T)``.

    Invariants, per participant and unit ``k`` (``W0`` the initial weights, ``x_n`` the patterns;
    ``Q`` and ``R`` are stored pattern-major):
    ``w_k = c_k (W0_k + sum_m R_km x_m)`` and ``w_k . x_n = c_k Q_kn`` with
    ``Q_kn = W0_k . x_n + sum_m R_km G_mn``, ``G = X X^T``. A step with rate ``a_k`` toward
    ``x_s`` sets ``c_k <- (1 - a_k) c_k``, ``R_ks += a_k / c_k``, ``Q_k += (a_k / c_k) G_s``: only the
    units inside the neighbourhood (``a_k > 0``) are touched. Norms ``|w_k|^2`` are updated in
    closed form; a unit-sum normalisation (supervised maps) only rescales ``c_k``.
    """
    st = _FactoredState(som, X)
    p = st.p
    winners = torch.empty_like(order)
    t0 = int(som.steps)
    watch = curve(som, order.shape[1])
    for t in it:
        s = order[:, t]
        Ds = st.c * st.Q[p, s]  # (P, U)  w_k . x_s
        win = (st.nrm - 2 * Ds).argmin(-1) if labels is None else labels[p, s]
        winners[:, t] = win
        if watch is not None:  # |w_win - x_s| from the invariants
            watch.add(t, (st.nrm[p, win] - 2 * Ds[p, win] + st.G[p, s, s]).clamp_min(0).sqrt().mean())
        st.step(s, win, Ds, t0 + t)
    st.form(som.weight)
    som.steps += order.shape[1]
    return winners


class _FactoredState:
    """The factors of :func:`fit_factored` (pattern-major ``G``, ``Q``, ``R``; per unit ``c``, the
    norms and, for a normalised map, the row sums) over patterns ``X`` ``(P, N, in)``, in float64:
    the recurrences are exact in real arithmetic; float64 keeps them so."""

    def __init__(self, som, X: torch.Tensor):
        P, N, _ = X.shape
        dt = torch.float64
        self.X, self.p = X, torch.arange(P, device=X.device)
        self.rule = som.rule
        self.W0 = W0 = som.weight
        # pattern-major layouts, so that the column of pattern s is one contiguous row
        self.G = torch.bmm(X, X.transpose(1, 2)).to(dt)  # (P, N, N)
        self.Q = torch.bmm(X, W0.transpose(1, 2)).to(dt)  # (P, N, U)   Q[n, k] = W0_k . x_n (+ sum_m R_km G_mn)
        self.R = X.new_zeros(P, N, som.units, dtype=dt)  # R[n, k] = R_kn
        self.nrm = (W0 * W0).sum(-1).to(dt)  # (P, U)
        self.c = X.new_ones(P, som.units, dtype=dt)
        self.rowsum = W0.sum(-1).to(dt)
        self.xsum = X.sum(-1).to(dt)  # (P, N)
        self.grid = som.grid.to(dt)
        self.normalise = isinstance(som.rule, SupervisedKohonen) and som.rule.normalise

    def step(self, s, win, Ds, t: int) -> None:
        """Step ``t`` of the schedule toward patterns ``s`` ``(P,)`` around ``win``; ``Ds`` the dot
        products ``w_k . x_s``."""
        p = self.p
        Gs = self.G[p, s]  # (P, N)
        eta, sigma = self.rule.schedule(t)
        a = float(eta) * self.rule.neighbourhood(self.grid, win, sigma.to(torch.float64))  # (P, U)
        b = 1 - a
        self.nrm = b * b * self.nrm + 2 * a * b * Ds + a * a * Gs[p, s].unsqueeze(-1)
        self.c = b * self.c
        on = (a > 0).any(0).nonzero()  # units inside any participant's neighbourhood
        lo, hi = int(on[0]), int(on[-1]) + 1  # a contiguous span of units: updated in place as a view
        u = a[:, lo:hi] / self.c[:, lo:hi]  # (P, k), zero outside the neighbourhoods
        self.Q[:, :, lo:hi].baddbmm_(Gs.unsqueeze(-1), u.unsqueeze(1))
        self.R[p, s, lo:hi] += u
        if self.normalise:
            self.rowsum = b * self.rowsum + a * self.xsum[p, s].unsqueeze(-1)
            k = 1.0 / self.rowsum.clamp_min(ROWSUM_FLOOR)
            self.nrm = self.nrm * k * k
            self.c = self.c * k
            self.rowsum = torch.ones_like(self.rowsum)
        self._fold_small()

    def _fold_small(self) -> None:
        """Fold scales ``c_k`` below ``FOLD_BELOW`` back into ``W0``, ``Q`` and ``R`` before they cost precision."""
        c = self.c
        small = c < FOLD_BELOW
        if bool(small.any()):
            pi, ki = small.nonzero(as_tuple=True)
            self.Q[pi, :, ki] *= c[pi, ki].unsqueeze(-1)
            self.R[pi, :, ki] *= c[pi, ki].unsqueeze(-1)
            c_fold = torch.ones_like(c)
            c_fold[pi, ki] = c[pi, ki]
            self.W0 = self.W0 * c_fold.unsqueeze(-1).to(self.W0.dtype)
            c[pi, ki] = 1.0

    def form(self, weight: torch.Tensor) -> None:
        """``w_k = c_k W0_k + sum_n (c_k R_kn) x_n`` into ``weight``, formed once (the scaled
        coefficients are O(1))."""
        c, W0, X = self.c, self.W0, self.X
        cR = (self.R * c.unsqueeze(1)).to(X.dtype)  # (P, N, U)
        weight.copy_(c.unsqueeze(-1).to(W0.dtype) * W0 + torch.bmm(cR.transpose(1, 2), X))


def rates_below_one(som) -> bool:
    return max(som.rule.eta0, som.rule.eta1) < 1


def refuse(som) -> str | None:
    """Why the factored arithmetic cannot train ``som`` (None if it can)."""
    if som.weight.device.type == "meta":
        return "needs the weights' values; on the meta device use 'online'"
    if not rates_below_one(som):
        return "needs learning rates below 1 (a unit may not jump onto a pattern)"
    return None


@register(Kohonen, SOM)
class Factored(Form):
    """``method='factored'``: 'auto' takes it when there are fewer patterns than inputs."""

    name, priority = "factored", 2

    def why_not(self, som, rule, call):
        return refuse(som)

    def suits(self, som, rule, call) -> bool:
        return call.X.shape[1] < som.n_in and rates_below_one(som) and som.weight.device.type != "meta"

    def run(self, som, rule, call) -> torch.Tensor:
        return fit_factored(som, call.X, call.order, call.labels, call.steps)
