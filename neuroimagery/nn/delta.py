"""The delta (Widrow-Hoff) rule (eq. 6.4) and its registered forms.

The rule's change is written once, in :class:`Delta`: ``dw_ji = rate * (y_j - a_j) * x_i``, with
:meth:`Delta.rate` (``eta``, or ``eta / B`` averaged over a batch of ``B`` patterns) and
:meth:`Delta.error` (the target ``y`` minus the actual output ``a``). Its forms below compute the
same change on other weight layouts and inputs, each registered for the rule and a learner
(:mod:`.forms`), each tested against the dense rule:

* :class:`Delta` itself on a dense :class:`~.connections.Connection` (``(P, out, in)`` weights):
  one product per step (an :class:`~.change.Outer` change);
* ``delta_binary`` (a connection over a sequence): 0/1 inputs in mini-batches on the CPU, only the
  weight columns of the active inputs read and written (:func:`delta_binary`); inputs and 0/1
  targets may come as :class:`~.binary.ActiveRows`;
* ``index``, ``sparse``, ``dense`` (a :class:`~.local.LocalConnection`, ``(P, n, K)`` weights):
  patterns given by their active units, sparse (binary or few active units) and dense activity.

Every sparse form adds in index order (``index_add_`` on the CPU), so its numbers do not depend on
the thread count.
"""
from __future__ import annotations

import torch

from . import local_kernel, monitor
from .change import Outer
from .connections import Connection
from .forms import Form, register
from .functional import check_rate, transpose_into, transposed_copy
from .binary import ActiveRows
from .learning import error_curve, length
from .local import LocalConnection
from .rules import Rule, check_reduction


class Delta(Rule):
    """Delta (Widrow-Hoff) rule (eq. 6.4): ``dw_ji = eta (y_j - a_j) x_i``.

    ``target`` is the desired output ``y``, ``post`` the actual output ``a``. Thesis: eta = 0.1.
    """

    def __init__(self, eta: float = 0.1, reduction: str = "sum") -> None:
        super().__init__()
        self.eta = check_rate("eta", eta)
        self.reduction = check_reduction(reduction)

    needs = ("post", "target")

    def step_gain(self, pre, post):
        """``rate * max_p sum_b |x_b|^2``: a step multiplies the batch's errors by
        ``I - rate X X^T``, which shrinks every one of them while ``rate`` times the largest
        eigenvalue of ``X X^T`` (at most its trace, ``sum_b |x_b|^2``) is below 2 (the
        Widrow-Hoff stability bound)."""
        return self.rate(pre.shape[1]) * torch.linalg.vector_norm(pre.flatten(1), dim=1).amax().square()

    def gain_formula(self) -> str:
        return f"rate * sum_b |x_b|^2 (eta={self.eta}, reduction={self.reduction!r}: rate = eta{' / B' if self.reduction == 'mean' else ''})"

    def rate(self, batch: int) -> float:
        """The rate of a batch of ``batch`` patterns: ``eta`` (summed) or ``eta / batch`` (averaged)."""
        return self.eta / batch if self.reduction == "mean" else self.eta

    @staticmethod
    def error(post: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """The rule's error, target minus actual output: ``y - a``."""
        return target - post

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, target: torch.Tensor, **_) -> Outer:
        """``rate (y - a)^T x``, an outer product accumulated straight into the weights when applied."""
        return Outer(weight, None, self.error(post, target), pre, self.rate(pre.shape[1]))

    def extra_repr(self) -> str:
        return f"eta={self.eta}"


# ------------------------------------------------------------------ a dense connection, over a sequence
@torch.no_grad()
def delta_binary(weight: torch.Tensor, X, Y, eta: float, batch: int, progress=None,
                 curve: str | None = None) -> torch.Tensor:
    """Delta rule (``Delta(eta, reduction='sum')``) on binary inputs, in mini-batches, in place;
    returns the trained weights transposed ``(P, in, out)`` (what it trained them in).

    ``weight`` ``(P, out, in)``, ``X`` ``(P, N, in)`` 0/1 or an :class:`~.binary.ActiveRows` of
    them, ``Y`` ``(P, N, out)`` targets (or an :class:`~.binary.ActiveRows` of 0/1 targets). Each
    mini-batch of ``batch`` patterns is evaluated at the same weights and the summed change is
    applied, exactly as ``conn.learn(pre=x, post=conn(x), target=y)`` with a ``Delta`` rule would do
    (identity transfer), but only the weight columns of active inputs are read and written.

    Deterministic: a prediction adds its active weight columns one after the other, and each
    weight receives its changes in the order of the mini-batch's patterns (``index_add_``, which
    adds in index order on the CPU; ``index_put_(accumulate=True)`` does not, with several
    threads). Every number is thus a fixed sequence of IEEE additions and products, the same at
    any thread count and on any CPU. ``curve`` names the training curve (:mod:`.monitor`) of the
    mini-batches' squared error before their change, reported when a reader listens.
    """
    P, O, I = weight.shape
    N = length(X)
    watch = monitor.Curve(curve, -(-N // batch)) if curve and monitor.active() else None
    table = transposed_copy(weight)  # (P, I, O): participant p's weight column i is row p I + i of rows_of
    rows_of = table.view(P * I, O)
    idx, sizes = _bags(X, P, I)
    first = sizes.cumsum(0) - sizes  # where each bag starts in idx
    starts = range(0, N, batch)
    for b, s in enumerate(progress(starts) if progress is not None else starts):
        e = min(s + batch, N)
        counts = sizes[s * P:e * P]
        lo = int(first[s * P])
        hi = lo + int(counts.sum())
        if hi == lo:
            continue
        offsets = first[s * P:e * P] - lo
        bag_idx = idx[lo:hi]
        # each prediction adds its active weight columns one after the other, in ascending order
        out = torch.nn.functional.embedding_bag(bag_idx, rows_of, offsets, mode="sum").view(e - s, P, O).transpose(0, 1)
        y = Y.rows(s, e) if isinstance(Y, ActiveRows) else Y[:, s:e]
        if watch is not None:
            watch.add(b, (y - out).pow(2).sum(-1).mean())
        err = (eta * Delta.error(out, y)).transpose(0, 1).reshape(-1, O)  # (bags, O), bag order
        rows_of.index_add_(0, bag_idx, err.repeat_interleave(counts, dim=0))
    transpose_into(weight, table)
    return table


def _bags(X, P: int, I: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The active inputs of every pattern, once: flat weight rows ``p I + i`` in bags of
    (pattern, participant) order, so that a mini-batch is one contiguous run of bags; within a bag
    the inputs ascend. Returns the rows and each bag's size."""
    if isinstance(X, ActiveRows):
        ind = X.index.transpose(0, 1)  # (n, p, d): ascending units, the pads last
        valid = ind >= 0
        idx = (torch.arange(P).view(1, P, 1) * I + ind.long())[valid]
        return idx, valid.sum(-1).reshape(-1)
    nz = (X > 0.5).transpose(0, 1).nonzero(as_tuple=False)  # (n, p, i), sorted
    return nz[:, 1] * I + nz[:, 2], torch.bincount(nz[:, 0] * P + nz[:, 1], minlength=X.shape[1] * P)


@register(Delta, Connection)
class BinarySequence(Form):
    """:func:`delta_binary`: every input 0 or 1, the identity transfer, the weights on the CPU."""

    name = "delta_binary"

    def why_not(self, conn, rule, call):
        pre, post, kw = call.pre, call.post, call.kw
        why = "does not apply to this rule or these inputs"
        if (type(rule) is not Delta or rule.reduction != "sum" or post is not None or set(kw) != {"target"}
                or conn.transfer_name != "identity" or conn.weight.device.type != "cpu"):
            return why
        if any(not isinstance(x, (torch.Tensor, ActiveRows)) for x in (pre, kw["target"])):
            return why
        return None if isinstance(pre, ActiveRows) or bool(((pre == 0) | (pre == 1)).all()) else why

    @torch.no_grad()
    def run(self, conn, rule, call) -> None:
        P, pre, target = conn.participants, call.pre, call.kw["target"]
        X = pre.expand(P, -1, -1) if isinstance(pre, torch.Tensor) and pre.dim() == 2 else pre
        Y = target.expand(P, -1, -1) if isinstance(target, torch.Tensor) and target.dim() == 2 else target
        conn.keep_transposed(delta_binary(conn.weight, X, Y, rule.eta, call.batch, call.progress, curve=error_curve(conn)))


# ------------------------------------------------------------------ a local connection, one step
def _target(conn, call) -> torch.Tensor:
    if call.kw.get("target") is None:
        raise ValueError(f"connection {conn.name!r}: the delta rule needs a target")
    return call.kw["target"]


@register(Delta, LocalConnection)
class Index(Form):
    """Binary patterns given by their active units: ``pre_index`` ``(P, B, D)`` and
    ``target_index`` ``(P, B, T)`` (-1 = no unit; repeats count once, as in a 0/1 map); the change
    of the 0/1 maps without forming them."""

    name = "index"

    def why_not(self, conn, rule, call):
        return None if call.kw.get("pre_index") is not None else "needs pre_index"

    @torch.no_grad()
    def run(self, conn, rule, call) -> None:
        pre_index, target_index = call.kw["pre_index"], call.kw.get("target_index")
        if target_index is None:
            raise ValueError(f"connection {conn.name!r}: the index form needs target_index")
        flat, delta = _index_change(conn, rule, pre_index, target_index)
        call.out.view(-1).index_add_(0, flat, delta)


@torch.no_grad()
def _index_change(conn, rule, pre_index: torch.Tensor, target_index: torch.Tensor):
    """The flat weight indices and changes of :class:`Index` (``index_add_`` order = pattern order)."""
    P, B, D = pre_index.shape
    n, K = conn.n_in, conn.K
    pre = pre_index.reshape(P * B, D)
    # a repeated active unit counts once (0/1 input)
    dup = torch.zeros_like(pre, dtype=torch.bool)
    for d in range(1, D):
        dup[:, d] = (pre[:, :d] == pre[:, d:d + 1]).any(-1)
    valid = (pre >= 0) & ~dup
    safe = pre.clamp_min(0)
    o = conn.target_of[safe]  # (R, D, K) outputs reached
    ok = valid.unsqueeze(-1) & (o < n)
    oc = o.clamp_max(n - 1)
    part = torch.arange(P).repeat_interleave(B)  # (R,)
    k = torch.arange(K).view(1, 1, K).expand_as(oc)
    flat = (part.view(-1, 1, 1) * n + oc) * K + k  # (R, D, K) weight of each reached output from its own unit
    wv = conn.weight.view(-1)
    post = wv[flat]  # the unit's own contribution
    # contributions of the pattern's other active units: only those within twice the radius matter
    c = conn.coords[safe]  # (R, D, 3)
    for d in range(D):
        for d2 in range(D):
            if d2 == d:
                continue
            near = valid[:, d] & valid[:, d2] & ((c[:, d] - c[:, d2]).abs().max(-1).values <= 2 * conn.radius)
            r = near.nonzero().squeeze(-1)
            if r.numel() == 0:
                continue
            oo = oc[r, d]  # (r, K)
            k2 = conn.offset_index(safe[r, d2].unsqueeze(-1).expand_as(oo), oo)
            w = wv[((part[r].unsqueeze(-1) * n + oo) * K + k2.clamp_min(0))]
            post[r, d] += torch.where(ok[r, d] & (k2 >= 0), w, torch.zeros_like(w))
    tgt = target_index.reshape(P * B, -1)
    hit = (oc.unsqueeze(-1) == tgt.view(P * B, 1, 1, -1)).any(-1)  # (R, D, K): the target map at each output
    err = Delta.error(post, hit.to(post.dtype))
    return flat.reshape(-1), torch.where(ok, rule.rate(B) * err, torch.zeros_like(err)).reshape(-1)


def _sparse(pre: torch.Tensor) -> bool:
    """Binary activity, or graded with at most a quarter of the units active."""
    return bool(((pre == 0) | (pre == 1)).all()) or float((pre != 0).float().mean()) <= 0.25


@register(Delta, LocalConnection)
class Sparse(Form):
    """``pre`` ``(P, B, n)`` binary or with few active units: only the weights of the active inputs
    are read and written; ``post`` (when None) by :meth:`LocalConnection.net_binary`."""

    name = "sparse"

    def why_not(self, conn, rule, call):
        if call.pre is None:
            return "needs pre"
        return None if _sparse(call.pre) else "needs binary or sparse input"

    @torch.no_grad()
    def run(self, conn, rule, call) -> None:
        pre, target = call.pre, _target(conn, call)
        P, B, n = pre.shape
        post = call.post
        if (post is None and target.shape == pre.shape and call.out.is_contiguous()
                and local_kernel.available(conn.weight, pre, target, call.out)):
            local_kernel.learn_sparse(conn.weight, conn.target_of, pre, target, rule.rate(B), call.out)
            return
        if post is None:
            post = conn.net_binary(pre.reshape(P * B, n), torch.arange(P).repeat_interleave(B)).view(P, B, n)
        err = Delta.error(post, target)  # (P, B, n)
        if local_kernel.available(pre, err, call.out) and call.out.is_contiguous():
            local_kernel.delta_sparse(pre, err, conn.target_of, rule.rate(B), call.out)
            return
        p, b, i = (pre != 0).nonzero(as_tuple=True)
        o = conn.target_of[i]  # (A, K)
        k = torch.arange(conn.K).expand_as(o)
        e = torch.cat([err, err.new_zeros(P, B, 1)], -1)[p.unsqueeze(1), b.unsqueeze(1), o]  # (A, K)
        e = e * pre[p, b, i].unsqueeze(1)  # graded input: the rule's pre factor
        flat = ((p.unsqueeze(1) * n + o.clamp_max(n - 1)) * conn.K + k)
        delta = torch.where(o < n, rule.rate(B) * e, torch.zeros_like(e))
        call.out.view(-1).index_add_(0, flat.reshape(-1), delta.reshape(-1))


@register(Delta, LocalConnection)
class Dense(Form):
    """Any ``pre`` ``(P, B, n)``: the change of every stored weight, one offset at a time."""

    name, priority = "dense", 6

    def why_not(self, conn, rule, call):
        return None if call.pre is not None else "needs pre"

    @torch.no_grad()
    def run(self, conn, rule, call) -> None:
        pre, target = call.pre, _target(conn, call)
        P, B, n = pre.shape
        post = conn.net(pre) if call.post is None else call.post
        err = Delta.error(post, target)  # (P, B, n)
        pad = torch.cat([pre, pre.new_zeros(P, B, 1)], -1)
        d = torch.stack([(err * pad[..., conn.source[:, k]]).sum(1) for k in range(conn.K)], -1) * rule.rate(B)
        call.out.add_(d * (conn.source < n).unsqueeze(0))
