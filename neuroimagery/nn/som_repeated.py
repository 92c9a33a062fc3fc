"""The closed form of online Kohonen training (eq. 4.5) when one labelled pattern is presented
again and again and only its forced winner moves (``SOM.fit(method='repeated')``).

With a forced winner ``k``, a neighbourhood that is the winner alone (every other unit's
``theta`` below the rule's cutoff) and the same rate ``eta`` at every step, ``T`` online steps
``w_k <- w_k + eta (x - w_k)`` toward the same pattern ``x`` collapse to
``w_k <- x + (1 - eta)^T (w_k - x)``; no other unit changes. This is how chapter 7's C3 learns
(50 presentations of one outcome per success, a neighbourhood far below one unit). Same winners
as the plain rule, the same weights up to float rounding (``tests/test_som.py``).

:func:`applies` is the test :meth:`SOM.fit` runs before choosing this form (``None`` if it
applies, else why not); the rate and radius are the rule's own schedule at the steps trained.
"""
from __future__ import annotations

import torch

from .forms import Form, register
from .rules import Kohonen, SupervisedKohonen
from .som import SOM, curve
from .som_online import supports


def _supports(rule) -> bool:
    return supports(rule) and not (isinstance(rule, SupervisedKohonen) and rule.normalise)


def applies(som, X: torch.Tensor, order: torch.Tensor, labels: torch.Tensor | None) -> str | None:
    """``None`` when the closed form gives the plain rule's steps for this call, else the reason."""
    if labels is None:
        return "needs forced winners (labels)"
    if som.weight.device.type == "meta":
        return "needs the order's values; on the meta device use 'online'"
    if not _supports(som.rule):
        return "needs the Kohonen step without unit-sum normalisation"
    if order.shape[1] > 1 and not bool((order == order[:, :1]).all()):
        return "needs the same pattern at every step"
    t0, T = int(som.steps), order.shape[1]
    (eta_a, sigma_a), (eta_b, sigma_b) = som.rule.schedule(t0), som.rule.schedule(t0 + T - 1)
    if not (torch.equal(eta_a, eta_b) and torch.equal(sigma_a, sigma_b)):
        return "needs a constant rate and radius over the steps trained"
    p = torch.arange(som.participants, device=order.device)
    win = labels[p, order[:, 0]]
    theta = som.rule.neighbourhood(som.grid, win, sigma_a.to(som.grid.device))
    if not bool(((theta > 0).sum(-1) == 1).all()):
        return "needs a neighbourhood that is the winner alone (every other unit below the cutoff)"
    return None


@torch.no_grad()
def fit_repeated(som, X: torch.Tensor, order: torch.Tensor, labels: torch.Tensor, it) -> torch.Tensor:
    """``T`` steps toward ``X[p, order[p, 0]]`` on its forced winner, in one update; returns the
    winners ``(P, T)``. The caller has checked :func:`applies`."""
    P, T = order.shape
    p = torch.arange(P, device=order.device)
    s = order[:, 0]
    win = labels[p, s]
    eta, _ = som.rule.schedule(int(som.steps))
    x = X[p, s]  # (P, in)
    w = som.weight[p, win]
    watch = curve(som, T)
    if watch is not None:  # |w_t - x| = (1 - eta)^t |w_0 - x| before step t
        d0 = (w - x).norm(dim=-1).mean()
        for t in it:
            watch.add(t, d0 * (1.0 - float(eta)) ** t)
    som.weight[p, win] = x + (1.0 - float(eta)) ** T * (w - x)
    som.steps += T
    return win.unsqueeze(1).expand(P, T).clone()


@register(Kohonen, SOM)
class Repeated(Form):
    """``method='repeated'``: 'auto' takes it for labelled maps where :func:`applies` holds."""

    name, priority = "repeated", 1

    def why_not(self, som, rule, call):
        return "needs the pattern order" if call.order is None else applies(som, call.X, call.order, call.labels)

    def suits(self, som, rule, call) -> bool:
        return call.labels is not None

    def run(self, som, rule, call) -> torch.Tensor:
        return fit_repeated(som, call.X, call.order, call.labels, call.steps)
