"""The products and the sparse delta-rule change of :class:`~neuroimagery.nn.local.LocalConnection`
compiled with numba, for CPU tensors: the same operations, in the same order, as the torch code
they stand for, so the two give the same numbers (``tests/test_exp6_kernels.py`` compares them); a
call costs its arithmetic instead of a dozen index tensors of ``active units x K`` entries.

* :func:`net_sparse` -- ``W x`` from the active units of each row: for each row, each active input
  ``i`` in ascending order and each offset ``k``, ``out[o] += w[o, k] x_i`` with
  ``o = target_of[i, k]`` (the order in which ``index_add_`` adds them in
  :meth:`~neuroimagery.nn.local.LocalConnection.net_binary`);
* :func:`net_dense` -- ``W x`` of any rows: ``out[o] = sum_k pad[source[o, k]] w[o, k]``, the
  offsets added in order from zero (as the offset loop of
  :meth:`~neuroimagery.nn.local.LocalConnection.net_rows`);
* :func:`delta_sparse` -- the delta rule's change at the weights of the active inputs,
  ``out[p, o, k] += rate (err[p, b, o] pre[p, b, i])`` for each pattern ``b`` and active input
  ``i`` in ascending order (the order of :class:`~neuroimagery.nn.delta.Sparse`'s ``index_add_``);
* :func:`learn_sparse` -- both for one participant after the other (output, error, change), so
  that a participant's weights are read and changed while they are in the cache.

Without numba, or for tensors elsewhere than on the CPU, the torch code runs.
"""
from __future__ import annotations

import numpy as np
import torch

from . import compiled


def available(*tensors: torch.Tensor) -> bool:
    """Whether the compiled loops can take these tensors: numba installed, CPU tensors of one
    floating dtype (float32 or float64) that no gradient flows through, and not while
    ``torch.compile`` traces."""
    if not compiled.available():
        return False
    dtypes = {t.dtype for t in tensors}
    if len(dtypes) != 1 or dtypes.pop() not in (torch.float32, torch.float64):
        return False
    grad = torch.is_grad_enabled()
    return all(t.device.type == "cpu" and not (grad and t.requires_grad) for t in tensors)


@compiled.jit  # shared by the compiled loops below
def _add_products(w, target_of, x, out):  # pragma: no cover (compiled)
    """``out[o] += w[o, k] x_i`` for each active input ``i`` of one row ``x`` in ascending order and each offset ``k``."""
    n = x.shape[0]
    K = target_of.shape[1]
    for i in range(n):
        v = x[i]
        if v != 0:
            for k in range(K):
                o = target_of[i, k]
                if o < n:
                    out[o] += w[o, k] * v


@compiled.jit
def _add_change(err, pre, target_of, rate, out):  # pragma: no cover (compiled)
    """``out[o, k] += rate (err[o] pre_i)`` for each active input ``i`` of one pattern in ascending order."""
    n = pre.shape[0]
    K = target_of.shape[1]
    for i in range(n):
        v = pre[i]
        if v != 0:
            for k in range(K):
                o = target_of[i, k]
                if o < n:
                    out[o, k] += rate * (err[o] * v)


def _net_sparse(w, target_of, x, group, out):  # pragma: no cover (compiled)
    for r in range(x.shape[0]):
        _add_products(w[group[r]], target_of, x[r], out[r])


def _net_dense(w, source, x, group, out):  # pragma: no cover (compiled)
    N, n = x.shape
    K = source.shape[1]
    for r in range(N):
        g = group[r]
        for o in range(n):
            acc = out[r, o]  # zero
            for k in range(K):
                s = source[o, k]
                if s < n:  # outside the grid reads zero: adding its zero product changes nothing
                    acc += x[r, s] * w[g, o, k]
            out[r, o] = acc


def _delta_sparse(pre, err, target_of, rate, out):  # pragma: no cover (compiled)
    P, B, _ = pre.shape
    for p in range(P):
        for b in range(B):
            _add_change(err[p, b], pre[p, b], target_of, rate, out[p])


def _learn_sparse(w, target_of, pre, target, rate, out):  # pragma: no cover (compiled)
    P, B, n = pre.shape
    post = np.zeros((B, n), dtype=pre.dtype)
    for p in range(P):  # a participant's weights read for its output and changed while in the cache
        post[:, :] = 0
        for b in range(B):
            _add_products(w[p], target_of, pre[p, b], post[b])
        for b in range(B):
            for o in range(n):
                post[b, o] = target[p, b, o] - post[b, o]  # the error
        for b in range(B):
            _add_change(post[b], pre[p, b], target_of, rate, out[p])


_fn = compiled.Kernels(globals())  # the compiled loops, each once


def _np(t: torch.Tensor) -> np.ndarray:
    return t.detach().contiguous().numpy()


def net_sparse(weight: torch.Tensor, target_of: torch.Tensor, x: torch.Tensor, group: torch.Tensor) -> torch.Tensor:
    """``W x`` ``(N, n)`` of rows ``x`` ``(N, n)`` from their active units, row r through participant
    ``group[r]``'s weights ``(P, n, K)`` (``x`` in the weights' dtype)."""
    out = torch.zeros(x.shape, dtype=weight.dtype)
    _fn("net_sparse")(_np(weight), _np(target_of), _np(x), _np(group.long()), out.numpy())
    return out


def net_dense(weight: torch.Tensor, source: torch.Tensor, x: torch.Tensor, group: torch.Tensor) -> torch.Tensor:
    """``W x`` ``(N, n)`` of any rows ``x`` ``(N, n)``, row r through participant ``group[r]``'s
    weights ``(P, n, K)`` (``x`` in the weights' dtype)."""
    out = torch.zeros(x.shape, dtype=weight.dtype)
    _fn("net_dense")(_np(weight), _np(source), _np(x), _np(group.long()), out.numpy())
    return out


def delta_sparse(pre: torch.Tensor, err: torch.Tensor, target_of: torch.Tensor, rate: float, out: torch.Tensor) -> None:
    """Add the delta rule's change ``(P, n, K)`` of patterns ``pre`` ``(P, B, n)`` with errors ``err``
    ``(P, B, n)`` into ``out`` (contiguous, the dtype of ``pre``) in place."""
    if not out.is_contiguous():
        raise ValueError("delta_sparse: out must be contiguous")
    rate = np.float32(rate) if out.dtype == torch.float32 else np.float64(rate)
    _fn("delta_sparse")(_np(pre), _np(err), _np(target_of), rate, out.numpy())


def learn_sparse(weight: torch.Tensor, target_of: torch.Tensor, pre: torch.Tensor, target: torch.Tensor, rate: float,
                 out: torch.Tensor) -> None:
    """:func:`net_sparse` of ``pre`` ``(P, B, n)`` (row ``(p, b)`` through participant ``p``), the error
    ``target - post`` and :func:`delta_sparse`, one participant after the other: the same numbers
    (each participant's output depends on its weights alone), its weights read and changed while
    in the cache. ``out`` may be ``weight`` itself."""
    if not out.is_contiguous():
        raise ValueError("learn_sparse: out must be contiguous")
    rate = np.float32(rate) if out.dtype == torch.float32 else np.float64(rate)
    _fn("learn_sparse")(_np(weight), _np(target_of), _np(pre), _np(target), rate, out.numpy())
