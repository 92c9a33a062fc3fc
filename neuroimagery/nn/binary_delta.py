"""The delta rule (eq. 6.4) on binary inputs in mini-batches, registered as an implementation of
:class:`~neuroimagery.nn.Delta` over a sequence (:mod:`neuroimagery.nn.learning`): only the weight
columns of the active inputs are read and written, so the cost grows with the number of edge
pixels, not the map size. Chosen when every input is 0 or 1 and the weights are on the CPU."""
from __future__ import annotations

import torch

from . import monitor
from .learning import IndexedRows, Kernel, error_curve, register
from .rules import Delta


@torch.no_grad()
def delta_binary(weight: torch.Tensor, X: torch.Tensor, Y: torch.Tensor, eta: float, batch: int, progress=None,
                 curve: str | None = None) -> None:
    """Delta rule (``Delta(eta, reduction='sum')``) on binary inputs, in mini-batches, in place.

    ``weight`` ``(P, out, in)``, ``X`` ``(P, N, in)`` 0/1, ``Y`` ``(P, N, out)`` targets. Each
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
    watch = monitor.Curve(curve, -(-X.shape[1] // batch)) if curve and monitor.active() else None
    P, O, I = weight.shape
    N = X.shape[1]
    rows_of = weight.transpose(1, 2).contiguous().view(P * I, O)  # participant p's weight column i is row p I + i
    # the active inputs of every pattern, once: bags in (pattern, participant) order, so that a
    # mini-batch is one contiguous run of bags; within a bag the inputs ascend
    nz = (X > 0.5).transpose(0, 1).nonzero(as_tuple=False)  # (n, p, i), sorted
    idx = nz[:, 1] * I + nz[:, 2]
    sizes = torch.bincount(nz[:, 0] * P + nz[:, 1], minlength=N * P)  # active inputs per bag
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
        y = Y[:, s:e]
        if watch is not None:
            watch.add(b, (y - out).pow(2).sum(-1).mean())
        err = (eta * (y - out)).transpose(0, 1).reshape(-1, O)  # (bags, O), bag order
        rows_of.index_add_(0, bag_idx, err.repeat_interleave(counts, dim=0))
    weight.copy_(rows_of.view(P, I, O).transpose(1, 2))


def _applies(conn, rule, pre, post, batch, kw) -> bool:
    target = kw.get("target")
    if (type(rule) is not Delta or rule.reduction != "sum" or post is not None or set(kw) != {"target"}
            or conn.transfer_name != "identity" or conn.weight.device.type != "cpu"):
        return False
    if any(not isinstance(x, torch.Tensor) or isinstance(x, IndexedRows) for x in (pre, target)):
        return False
    return bool(((pre == 0) | (pre == 1)).all())


@torch.no_grad()
def _run(conn, rule, pre, post, batch, progress, kw) -> None:
    P = conn.participants
    X = pre.expand(P, -1, -1) if pre.dim() == 2 else pre
    Y = kw["target"].expand(P, -1, -1) if kw["target"].dim() == 2 else kw["target"]
    delta_binary(conn.weight, X, Y, rule.eta, batch, progress, curve=error_curve(conn))
    return None


register(Kernel("delta_binary", _applies, _run))
