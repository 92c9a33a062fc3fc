"""Products whose inputs come from a small finite set, computed once per distinct input and looked
up: :class:`RowCache` (keyed by integer, per participant) and :func:`distinct_rows`. The rows equal
those of the product over the whole batch up to float rounding."""
from __future__ import annotations

import torch

MIN_ROWS = 8  # products over fewer rows may take another BLAS path (matrix-vector) with other rounding


class RowCache:
    """Per-participant outputs of ``fn`` for integer keys, each computed once.

    ``fn(keys)`` maps keys ``(P, L)`` to a tuple of ``(P, L, ...)`` tensors, one row per key, and
    must compute each row independently of the others (as a batched matrix product does). Calling
    the cache with keys ``(P, B)`` returns ``fn(keys)`` by evaluating only the keys it has not seen
    yet, over at least ``MIN_ROWS`` rows. The rows equal those of ``fn(keys)`` to float rounding,
    not bit for bit: BLAS may sum a product of other shapes in another order (with oneMKL on
    AVX-512, 8-row products round otherwise than larger ones).
    """

    def __init__(self, participants: int, n_keys: int, fn) -> None:
        self.fn = fn
        self.slot = torch.full((participants, n_keys), -1, dtype=torch.long)
        self.values: tuple[torch.Tensor, ...] | None = None

    def __call__(self, keys: torch.Tensor) -> tuple[torch.Tensor, ...]:
        P = self.slot.shape[0]
        pi = torch.arange(P).unsqueeze(1)
        flat = keys.reshape(P, -1)
        need = torch.zeros_like(self.slot, dtype=torch.bool)
        need[pi, flat] = True
        need &= self.slot < 0
        counts = need.sum(1)
        if int(counts.max()) > 0:
            L = max(int(counts.max()), MIN_ROWS)
            # each participant's new keys first (ascending), padded with its smallest key
            order = torch.sort((~need).to(torch.int8), dim=1, stable=True).indices[:, :L]
            pos = torch.arange(L).unsqueeze(0)
            real = pos < counts.unsqueeze(1)
            new = torch.where(real, order, torch.where(counts.unsqueeze(1) > 0, order[:, :1], flat[:, :1]))
            out = self.fn(new)
            base = 0 if self.values is None else self.values[0].shape[1]
            self.values = out if self.values is None else tuple(torch.cat([v, o], 1) for v, o in zip(self.values, out))
            pr, jr = real.nonzero(as_tuple=True)
            self.slot[pr, new[pr, jr]] = base + jr
        idx = self.slot[pi, flat]
        return tuple(v[pi, idx].reshape(*keys.shape, *v.shape[2:]) for v in self.values)


def distinct_rows(fn, x: torch.Tensor) -> torch.Tensor:
    """``fn(x)`` for ``x`` ``(P, B, n)`` computed on the distinct rows of ``x`` only.

    ``fn`` maps ``(P, L, n)`` to ``(P, L, ...)`` row by row (as :class:`RowCache`'s functions);
    the rows shared by every participant are evaluated once for each and gathered back.
    """
    P, B, n = x.shape
    u, inv = torch.unique(x.reshape(-1, n), dim=0, return_inverse=True)
    if u.shape[0] >= B:
        return fn(x)
    if u.shape[0] < MIN_ROWS:
        u = torch.cat([u, u[:1].expand(MIN_ROWS - u.shape[0], -1)])
    out = fn(u.unsqueeze(0).expand(P, -1, -1).contiguous())
    inv = inv.reshape(P, B)
    return out[torch.arange(P).unsqueeze(1), inv]
