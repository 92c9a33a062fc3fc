"""Closed forms of the online outstar Hebbian rule (eq. 4.2-4.3).

With one pattern per step the update ``W <- W (1 - eta x_i) + eta y_j x_i`` is affine in the weights,
so a whole training sequence reduces to a few matrix products. These functions give the same weights
as calling :meth:`neuroimagery.nn.AllToAll.learn` with :class:`neuroimagery.nn.Hebbian` once per
pattern (tested to ~1e-7), at a fraction of the cost.
"""
from __future__ import annotations

import torch

from .connections import AllToAll
from .rules import Hebbian


@torch.no_grad()
def hebbian_shared(weight0: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, eta: float) -> torch.Tensor:
    """Online outstar Hebbian training (eq. 4.2-4.3) of ``P`` participants on one shared sequence.

    The outstar Oja step ``w_ji <- (1 - eta x_i) w_ji + eta x_i y_j`` (``Hebbian(eta, 'outstar')``
    applied one pattern at a time) is affine in the weights with coefficients that depend only on
    the presented activity. After the sequence ``t = 1..T``::

        w_ji = a_i w0_ji + sum_t eta x_i^t y_j^t S_ti,   a_i = prod_t (1 - eta x_i^t),
        S_ti = prod_{s > t} (1 - eta x_i^s)

    so every participant's weights follow from one matrix product, exactly (the test suite checks
    this against ``Connection.learn`` step by step). ``weight0`` ``(P, out, in)``, ``pre``
    ``(T, in)``, ``post`` ``(T, out)``; returns the trained ``(P, out, in)``.
    """
    dt = torch.float64
    keep = 1.0 - eta * pre.to(dt)  # (T, in)
    # suffix products S_t = prod_{s>t} keep_s
    rev = torch.cumprod(torch.flip(keep, [0]), 0)
    suffix = torch.cat([torch.flip(rev, [0])[1:], torch.ones_like(keep[:1])], 0)
    a = rev[-1]  # (in,)
    b = post.to(dt).T @ (eta * pre.to(dt) * suffix)  # (out, in)
    out = torch.empty_like(weight0)
    for p in range(weight0.shape[0]):  # one participant at a time: no (P, out, in) float64 temporaries
        out[p] = (weight0[p].to(dt) * a + b).to(weight0.dtype)
    return out


def hebbian_online(weight0: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, eta: float) -> torch.Tensor:
    """Reference: the same training through ``AllToAll.learn`` one pattern at a time (slow)."""
    P, n_out, n_in = weight0.shape
    c = AllToAll(n_in, n_out, participants=P, init="zeros", rules=Hebbian(eta, "outstar"))
    c.weight.copy_(weight0)
    c.train()
    for t in range(pre.shape[0]):
        c.learn(pre[t].expand(P, 1, n_in), post[t].expand(P, 1, n_out))
    return c.weight.clone()


@torch.no_grad()
def hebbian_indexed(weight0: torch.Tensor, pre: torch.Tensor, post_index: torch.Tensor, post_set: torch.Tensor,
                    eta: float) -> torch.Tensor:
    """Online outstar Hebbian training with a different sequence per participant, in closed form.

    Same algebra as :func:`hebbian_shared`; the outputs come from a finite set ``post_set``
    ``(K, out)`` indexed by ``post_index`` ``(P, T)``, so the sum over time is first gathered per
    output pattern (``(P, K, in)``) and then expanded with one small product. ``pre`` ``(P, T, in)``.
    """
    return hebbian_indexed_many(lambda p: pre[p], [(weight0, post_index, post_set)], eta)[0]


@torch.no_grad()
def hebbian_indexed_many(pre_of, targets, eta: float) -> list[torch.Tensor]:
    """:func:`hebbian_indexed` for several connections that see the same presynaptic sequence.

    ``pre_of(p)`` gives participant ``p``'s sequence ``(T, in)``; ``targets`` is a list of
    ``(weight0 (P, out, in), post_index (P, T), post_set (K, out))``. The time products (the
    ``(T, in)`` suffix products of ``1 - eta x``) are formed once per participant and shared by
    every target; working one participant at a time keeps them small. Each participant's
    arithmetic is element for element that of the batched form, so the weights are identical.
    """
    outs = [torch.empty_like(w0) for w0, _, _ in targets]
    for p in range(targets[0][0].shape[0]):
        pre = pre_of(p).unsqueeze(0)  # (1, T, in)
        keep = 1.0 - eta * pre.float()
        rev = torch.cumprod(torch.flip(keep, [1]), 1)
        suffix = torch.cat([torch.flip(rev, [1])[:, 1:], torch.ones_like(keep[:, :1])], 1)
        a = rev[:, -1]  # (1, in)
        c = eta * pre.float() * suffix  # (1, T, in)
        _, T, n_in = pre.shape
        for out, (weight0, post_index, post_set) in zip(outs, targets):
            C = torch.zeros(1, post_set.shape[0], n_in)
            C.scatter_add_(1, post_index[p:p + 1].long().unsqueeze(-1).expand(1, T, n_in), c)
            b = torch.einsum("ko,pki->poi", post_set.float(), C)
            torch.mul(weight0[p:p + 1], a.unsqueeze(1), out=out[p:p + 1]).add_(b)
    return outs
