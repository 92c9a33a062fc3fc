"""Closed forms of the online outstar Hebbian rule (eq. 4.2-4.3), registered as forms of
:class:`~neuroimagery.nn.Hebbian` on a :class:`~neuroimagery.nn.Connection` over a sequence
(:mod:`neuroimagery.nn.forms`: ``conn.learn(pre, post, sequence=True)`` picks them). Each form
records what it formed the weights from (``conn.learnt_factors``), rebuilds the weights from it
and bounds the rounding of that rebuild (compact checkpoints).

With one pattern per step the update ``W <- W (1 - eta x_i) + eta y_j x_i`` is affine in the weights,
so a whole training sequence reduces to a few matrix products. These functions give the same weights
as calling :meth:`neuroimagery.nn.AllToAll.learn` with :class:`neuroimagery.nn.Hebbian` once per
pattern (tested to ~1e-7), at a fraction of the cost.
"""
from __future__ import annotations

import numpy as np
import torch

from . import compiled
from .connections import AllToAll, Connection
from .forms import Form, register
from .learning import IndexedRows
from .numerics import cast_bound, rounding_bound
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
def hebbian_indexed_many(pre_of, targets, eta: float, factors: list | None = None) -> list[torch.Tensor]:
    """:func:`hebbian_indexed` for several connections that see the same presynaptic sequence.

    ``pre_of(p)`` gives participant ``p``'s sequence ``(T, in)``; ``targets`` is a list of
    ``(weight0 (P, out, in), post_index (P, T), post_set (K, out))``. The time products (the
    ``(T, in)`` suffix products of ``1 - eta x``) are formed once per participant and shared by
    every target; working one participant at a time keeps them small. Each participant's
    arithmetic is element for element that of the batched form, so the weights are identical.

    ``factors``, if a list, receives one dict per target with what its weights are formed from:
    ``a`` ``(P, in)`` (the decay of the initial weights), ``C`` ``(P, K, in)`` (the time sums per
    output pattern) and ``post_set``; :func:`rebuild_indexed` forms the same weights from them
    and the initial weights.
    """
    outs = [torch.empty_like(w0) for w0, _, _ in targets]
    kept = [([], []) for _ in targets]
    for p in range(targets[0][0].shape[0]):
        pre = pre_of(p).unsqueeze(0)  # (1, T, in)
        keep = 1.0 - eta * pre.float()
        suffix, a = suffix_products(keep[0])
        suffix, a = suffix.unsqueeze(0), a.unsqueeze(0)  # (1, T, in), (1, in)
        c = eta * pre.float() * suffix  # (1, T, in)
        _, T, n_in = pre.shape
        for out, (weight0, post_index, post_set), (ka, kc) in zip(outs, targets, kept):
            C = torch.zeros(1, post_set.shape[0], n_in, device=c.device)
            C.scatter_add_(1, post_index[p:p + 1].long().unsqueeze(-1).expand(1, T, n_in), c)
            _form_indexed(out[p:p + 1], weight0[p:p + 1], a, C, post_set)
            if factors is not None:
                ka.append(a.clone())  # not a view: it would keep the (T, in) products alive
                kc.append(C)
    if factors is not None:
        factors.extend({"a": torch.cat(ka), "C": torch.cat(kc), "post_set": post_set.float().clone()}
                       for (ka, kc), (_, _, post_set) in zip(kept, targets))
    return outs


def suffix_products(keep: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """For ``keep`` ``(T, n)`` (float32): ``S_t = prod_{s > t} keep_s`` ``(T, n)`` and the whole
    product ``prod_s keep_s`` ``(n,)``, as ``torch.cumprod`` forms them from the last step back
    (each running product in float64, stored in float32). Compiled with numba when it is installed
    (one pass, every column at once; the same operations, so the same bits), torch otherwise."""
    if _suffix_kernel() is None or keep.dtype != torch.float32 or keep.device.type != "cpu":
        rev = torch.cumprod(torch.flip(keep, [0]), 0)
        return torch.cat([torch.flip(rev, [0])[1:], torch.ones_like(keep[:1])], 0), rev[-1]
    k = keep.contiguous()
    suffix, whole = torch.empty_like(k), torch.empty(k.shape[1], dtype=k.dtype)
    _suffix_kernel()(k.numpy(), suffix.numpy(), whole.numpy())
    return suffix, whole


def _suffix_loop(keep, suffix, whole):  # pragma: no cover  (compiled)
    T, n = keep.shape
    cum = np.ones(n, dtype=np.float64)
    for i in range(n):
        suffix[T - 1, i] = 1.0
    for t in range(T - 1, 0, -1):
        for i in range(n):
            cum[i] *= np.float64(keep[t, i])
            suffix[t - 1, i] = np.float32(cum[i])
    for i in range(n):
        cum[i] *= np.float64(keep[0, i])
        whole[i] = np.float32(cum[i])


_kernels = compiled.Kernels(globals())


def _suffix_kernel():
    """The compiled :func:`_suffix_loop`, or None without numba."""
    return _kernels("suffix_loop") if compiled.installed() else None


def _form_indexed(out: torch.Tensor, weight0: torch.Tensor, a: torch.Tensor, C: torch.Tensor,
                  post_set: torch.Tensor) -> None:
    """One participant's weights ``out`` ``(1, out, in)`` of :func:`hebbian_indexed_many`:
    ``a * w0 + post_set^T C``."""
    b = torch.einsum("ko,pki->poi", post_set.float(), C)
    torch.mul(weight0, a.unsqueeze(1), out=out).add_(b)


@torch.no_grad()
def rebuild_indexed(weight0: torch.Tensor, factors: dict) -> torch.Tensor:
    """The weights :func:`hebbian_indexed_many` trained from the initial ``weight0`` ``(P, out, in)``,
    formed again from one of its ``factors`` by the same products (identical on the same CPU and threads)."""
    a, C, post_set = factors["a"], factors["C"], factors["post_set"]
    P, n_out, n_in = weight0.shape
    if a.shape != (P, n_in) or C.shape[0] != P or C.shape[2] != n_in or post_set.shape != (C.shape[1], n_out):
        raise ValueError(f"Hebbian factors a {tuple(a.shape)}, C {tuple(C.shape)}, post_set {tuple(post_set.shape)} "
                         f"do not fit weights {tuple(weight0.shape)}")
    out = torch.empty_like(weight0)
    for p in range(P):
        _form_indexed(out[p:p + 1], weight0[p:p + 1], a[p:p + 1], C[p:p + 1], post_set)
    return out


# ------------------------------------------------------------------ registered forms
WHY = "does not apply to this rule or these inputs"


def _online_outstar(conn, rule, batch: int) -> bool:
    return type(rule) is Hebbian and rule.form == "outstar" and batch == 1 and conn.weight.dim() == 3


@register(Hebbian, Connection)
class Shared(Form):
    """One sequence ``(T, in)``, ``(T, out)`` for every participant: :func:`hebbian_shared`; its
    factors are the sequence and the rate."""

    name = kind = "hebbian_shared"

    def why_not(self, conn, rule, call):
        pre, post = call.pre, call.post
        ok = (_online_outstar(conn, rule, call.batch) and not call.kw and isinstance(pre, torch.Tensor)
              and isinstance(post, torch.Tensor) and pre.dim() == 2 and post.dim() == 2)
        return None if ok else WHY

    @torch.no_grad()
    def run(self, conn, rule, call) -> dict:
        conn.weight.copy_(hebbian_shared(conn.weight, call.pre, call.post, rule.eta))
        return {"kind": self.kind, "pre": call.pre, "post": call.post.contiguous(), "eta": rule.eta}

    @torch.no_grad()
    def rebuild(self, conn, f: dict) -> None:
        conn.weight.copy_(hebbian_shared(conn.weight, f["pre"], f["post"], f["eta"]))

    @torch.no_grad()
    def bound(self, f: dict, w0, saved, rows):
        """Float64 work: each term passes through at most ``2 T + 5`` roundings (``T`` factors of
        its decay, 3 more products, ``T`` sums over the steps, 2 to combine), then rounds to
        float32 (one more ulp)."""
        d = torch.float64
        w0 = w0.to(d).abs()
        pre, post, eta = f["pre"].to(d), f["post"][:, rows].to(d), float(f["eta"])
        keep = (1.0 - eta * pre).abs()  # the decays and suffix products of hebbian_shared, in absolute value
        rev = torch.cumprod(torch.flip(keep, [0]), 0)
        suffix = torch.cat([torch.flip(rev, [0])[1:], torch.ones_like(keep[:1])], 0)
        mag = rev[-1] * w0 + (post.abs().T @ (abs(eta) * pre.abs() * suffix)).unsqueeze(0)
        return rounding_bound(mag, 2 * pre.shape[0] + 5, d) + cast_bound(saved.to(d))


@register(Hebbian, Connection)
class Indexed(Form):
    """Outputs drawn from a small set (``post`` a shared :class:`IndexedRows`):
    :func:`hebbian_indexed_many`; its factors are the decays and the per-pattern sums."""

    name = kind = "hebbian_indexed"

    def why_not(self, conn, rule, call):
        pre, post = call.pre, call.post
        ok = (_online_outstar(conn, rule, call.batch) and not call.kw and isinstance(post, IndexedRows) and post.shared
              and (isinstance(pre, IndexedRows) or isinstance(pre, torch.Tensor)))
        return None if ok else WHY

    @torch.no_grad()
    def run(self, conn, rule, call) -> dict:
        pre, post = call.pre, call.post
        if isinstance(pre, IndexedRows):
            pre_of = pre.of
        else:
            pre_of = (lambda p: pre) if pre.dim() == 2 else (lambda p: pre[p])
        factors: list = []
        (w,) = hebbian_indexed_many(pre_of, [(conn.weight, post.index, post.table)], rule.eta, factors)
        conn.weight.copy_(w)
        return {"kind": self.kind, **factors[0]}

    @torch.no_grad()
    def rebuild(self, conn, f: dict) -> None:
        conn.weight.copy_(rebuild_indexed(conn.weight, f))

    @torch.no_grad()
    def bound(self, f: dict, w0, saved, rows):
        """``w = a w0 + sum_k post_k C_k`` in float32: ``K + 1`` terms."""
        d = torch.float64
        C = f["C"].to(d).abs()
        prod = torch.einsum("ko,pki->poi", f["post_set"][:, rows].to(d).abs(), C)
        return rounding_bound(f["a"].to(d).abs().unsqueeze(1) * w0.to(d).abs() + prod, C.shape[1] + 1)
