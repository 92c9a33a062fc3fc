"""A rule applied over a training sequence (``Connection.learn(..., sequence=True)``).

A sequence is ``T`` presentations applied one after the other, ``batch`` patterns at a time, each
group evaluated at the weights the previous group left (``batch=1``: the online rule of the
thesis). The plain form (:func:`run_plain`, the form ``'plain'`` registered in
:mod:`.connections`) does exactly that, calling :meth:`Connection.learn` once per group. Faster
forms of the same arithmetic are registered in :mod:`.forms` for the rule and the connection
(``@register(Hebbian, Connection)``) and the connection picks the first that applies to the
rule and the inputs' shape and sparsity (``method='auto'``); ``method='plain'`` forces the
step-by-step form. Each fast one is tested against the plain one (``tests/test_learning.py``):

* ``hebbian_shared``, ``hebbian_indexed`` (:mod:`.hebbian_closed_form`): outstar Hebbian, one
  pattern per step, over one sequence shared by every participant or with outputs drawn from a
  small set (``post`` an :class:`IndexedRows`): closed forms of the whole sequence;
* ``delta_binary`` (:mod:`.delta`): the delta rule on 0/1 inputs in mini-batches on the CPU,
  touching only the weight columns of the active inputs; the inputs and targets may be given by
  their active units (:class:`~.binary.ActiveRows`), never formed as dense rows.

A form may leave what it formed the weights from in ``conn.learnt_factors`` (a dict with its
``kind``), which compact checkpoints store instead of the weights; the plain form leaves ``None``.
"""
from __future__ import annotations

import warnings
from types import SimpleNamespace

import torch

from . import forms, monitor
from .binary import ActiveRows
from .functional import check_floating, checks_enabled


class IndexedRows:
    """A sequence of rows drawn from a small set: row ``t`` of participant ``p`` is
    ``table[index[p, t]]`` (``table`` ``(K, n)``, shared) or ``table[p, index[p, t]]`` (``table``
    ``(P, K, n)``, per participant). ``index`` ``(P, T)``. Kernels use the set; the plain form
    gathers the rows."""

    def __init__(self, table: torch.Tensor, index: torch.Tensor) -> None:
        if table.dim() not in (2, 3) or index.dim() != 2:
            raise ValueError(f"IndexedRows: table (K, n) or (P, K, n) and index (P, T), got {tuple(table.shape)}, "
                             f"{tuple(index.shape)}")
        if table.dim() == 3 and table.shape[0] != index.shape[0]:
            raise ValueError(f"IndexedRows: table of {table.shape[0]} participants, index of {index.shape[0]}")
        self.table, self.index = table, index.long()

    shared = property(lambda self: self.table.dim() == 2)
    width = property(lambda self: self.table.shape[-1])
    length = property(lambda self: self.index.shape[1])
    participants = property(lambda self: self.index.shape[0])

    def of(self, p: int) -> torch.Tensor:
        """Participant ``p``'s sequence ``(T, n)``."""
        return self.table[self.index[p]] if self.shared else self.table[p, self.index[p]]

    def rows(self, lo: int, hi: int) -> torch.Tensor:
        """Steps ``lo..hi`` of every participant ``(P, hi - lo, n)``."""
        idx = self.index[:, lo:hi]
        if self.shared:
            return self.table[idx]
        return self.table[torch.arange(self.participants).unsqueeze(1), idx]


ROWS = (IndexedRows, ActiveRows)  # sequences given otherwise than as a tensor


def length(x) -> int:
    """Number of steps of a sequence: ``(T, n)``, ``(P, T, n)``, :class:`IndexedRows` or
    :class:`~.binary.ActiveRows`."""
    return x.length if isinstance(x, ROWS) else x.shape[-2]


def rows(x, lo: int, hi: int, P: int) -> torch.Tensor:
    """Steps ``lo..hi`` of a sequence for ``P`` participants ``(P, hi - lo, n)``."""
    if isinstance(x, ROWS):
        return x.rows(lo, hi)
    return x[lo:hi].expand(P, -1, -1) if x.dim() == 2 else x[:, lo:hi]


def error_curve(conn) -> str:
    """The tag of a connection's training curve of squared errors (:mod:`.monitor`)."""
    return f"train/{conn.name or 'connection'}/squared_error"


def run_plain(conn, pre, post, batch: int, progress=None, **kw) -> None:
    """The plain form: :meth:`Connection.learn` once per group of ``batch`` steps, in order; a rule
    that reads the actual output (``Delta``, with no ``post``) gets the connection's output at
    the current weights. With a ``target`` and a reader listening (:mod:`.monitor`), each group's
    squared error before its change is the connection's training curve."""
    P, T = conn.participants, length(pre)
    starts = range(0, T, batch)
    watch = monitor.Curve(error_curve(conn), len(starts)) if "target" in kw and monitor.active() else None
    for b, s in enumerate(progress(starts) if progress is not None else starts):
        x = rows(pre, s, s + batch, P)
        y = rows(post, s, s + batch, P) if post is not None else conn(x)
        extra = {k: rows(v, s, s + batch, P) if k == "target" else v for k, v in kw.items()}
        if watch is not None:
            watch.add(b, (extra["target"] - y).pow(2).sum(-1).mean())
        conn.learn(x, y, **extra)


def learn_sequence(conn, pre, post=None, batch: int = 1, method: str = "auto", progress=None, **kw) -> None:
    """Train ``conn`` on a sequence (see the module docstring); ``progress`` optionally wraps the
    iterable of steps (e.g. a progress bar)."""
    if int(batch) < 1:
        raise ValueError(f"batch must be >= 1, got {batch}")
    P = conn.participants
    for name, x in (("pre", pre), ("post", post), ("target", kw.get("target"))):
        if x is None:
            continue
        if isinstance(x, ROWS):
            if x.participants != P:
                raise ValueError(f"{name}: {x.participants} participants for a connection of {P}")
        elif x.dim() not in (2, 3) or (x.dim() == 3 and x.shape[0] != P):
            raise ValueError(f"{name} of connection {conn.name!r} must be (T, n) or ({P}, T, n), got {tuple(x.shape)}")
        else:
            check_floating(f"{name} of connection {conn.name!r}", x)
    # the sequence in the weights' dtype, so they keep it
    cast = (lambda x: x if x is None or isinstance(x, IndexedRows) or x.dtype == conn.weight.dtype
            else x.to(conn.weight.dtype))  # ActiveRows: read densely in the weights' dtype
    pre, post = cast(pre), cast(post)
    if kw.get("target") is not None:
        kw = {**kw, "target": cast(kw["target"])}
    T = length(pre)
    if any(x is not None and length(x) != T for x in (post, kw.get("target"))):
        raise ValueError("pre, post and target must have the same number of steps")
    conn.learnt_factors = None
    _learn(conn, pre, post, batch, method, progress, kw)
    if not getattr(conn, "warned_step", True) and checks_enabled(conn.weight) and not _finite(conn.weight):
        conn.warned_step = True  # one pass over the weights per sequence: the fast forms check no step
        warnings.warn(f"connection {conn.name!r}: its weights are no longer finite after this sequence "
                      "(learning diverged: lower eta or the batch; this warning is given once)", stacklevel=4)
    if monitor.active():  # the final state of every implementation, closed forms included
        w = conn.weight.detach()
        monitor.record(f"train/{conn.name or 'connection'}/weight_norm_final", w.flatten(1).norm(dim=1).mean(), T)
        monitor.record(f"train/{conn.name or 'connection'}/weight_max_final", w.amax(), T)


def _finite(w: torch.Tensor) -> bool:
    """Whether every weight is finite: its least and greatest are (a NaN makes both NaN), in one
    pass without a mask of the weights' size."""
    if not w.numel():
        return True
    lo, hi = torch.aminmax(w)
    return bool(torch.isfinite(lo) & torch.isfinite(hi))


def _learn(conn, pre, post, batch, method, progress, kw) -> None:
    call = SimpleNamespace(pre=pre, post=post, batch=int(batch), progress=progress, kw=kw)
    rule = conn.rules[0] if len(conn.rules) == 1 else None
    if rule is None and method not in ("auto", "plain"):  # the fast forms train one rule
        names = forms.names(conn)
        if method not in names:
            raise ValueError(f"method must be 'auto' or one of {names}, got {method!r}")
        raise ValueError(f"method={method!r} does not apply to this rule or these inputs")
    form = forms.choose(conn, rule, call, "plain" if rule is None else method)
    conn.learnt_factors = form.run(conn, rule, call)
