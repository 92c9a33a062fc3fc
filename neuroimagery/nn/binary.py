"""Products of weights with binary (0/1) activity, computed as sums of the weight rows of the active
units: the cost grows with the number of active units (edge pixels), not with the map size. The
forward models of Experiments 3 and 4 read their 32x32 edge maps this way."""
from __future__ import annotations

import numpy as np
import torch


def binary_matmul(weight_t: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``W x`` for binary ``x`` ``(P, B, in)``, given ``weight_t = W.transpose(1, 2)`` ``(P, in, out)``.

    Exactly ``torch.bmm(x, W^T)`` for 0/1 inputs, computed as the sum of the weight rows of the
    active input units (``embedding_bag``), so the cost grows with the number of edge pixels
    instead of the map size.
    """
    P, I, O = weight_t.shape
    Pb, B, Ix = x.shape
    if Ix != I or Pb != P:
        raise ValueError(f"binary_matmul: x {tuple(x.shape)} does not fit weights {tuple(weight_t.shape)}")
    nz = (x > 0.5).nonzero(as_tuple=False)  # sorted by (p, b, i)
    counts = torch.bincount(nz[:, 0] * B + nz[:, 1], minlength=P * B)
    offsets = torch.zeros(P * B, dtype=torch.long)
    offsets[1:] = counts.cumsum(0)[:-1]
    flat_idx = nz[:, 0] * I + nz[:, 2]
    out = torch.nn.functional.embedding_bag(flat_idx, weight_t.reshape(P * I, O), offsets, mode="sum")
    return out.reshape(P, B, O)



def sparse_matmul(weight_t: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``W x`` for graded, mostly-zero ``x`` ``(P, B, in)``, given ``weight_t = W.transpose(1, 2)``
    ``(P, in, out)``: the weight rows of the non-zero input units summed, each weighted by its
    activity (``embedding_bag`` with per-sample weights); :func:`binary_matmul` for 0/1 inputs."""
    P, I, O = weight_t.shape
    Pb, B, Ix = x.shape
    if Ix != I or Pb != P:
        raise ValueError(f"sparse_matmul: x {tuple(x.shape)} does not fit weights {tuple(weight_t.shape)}")
    nz = (x != 0).nonzero(as_tuple=False)  # sorted by (p, b, i)
    counts = torch.bincount(nz[:, 0] * B + nz[:, 1], minlength=P * B)
    offsets = torch.zeros(P * B, dtype=torch.long)
    offsets[1:] = counts.cumsum(0)[:-1]
    flat_idx = nz[:, 0] * I + nz[:, 2]
    vals = x[nz[:, 0], nz[:, 1], nz[:, 2]].to(weight_t.dtype)
    out = torch.nn.functional.embedding_bag(flat_idx, weight_t.reshape(P * I, O), offsets, mode="sum",
                                            per_sample_weights=vals)
    return out.reshape(P, B, O)

def binary_matmul_rows(table: torch.Tensor, group: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``W_g x`` for a flat batch of binary rows ``x`` ``(N, in)``, each with its own weight matrix.

    ``table`` ``(G, in, out)`` holds the transposed weights of ``G`` matrices (for instance one per
    participant and forward model) and ``group`` ``(N,)`` says which one each row uses. Like
    :func:`binary_matmul`, the cost grows with the number of active input units.
    """
    G, I, O = table.shape
    N = x.shape[0]
    nz = (x if x.dtype == torch.bool else x > 0.5).nonzero(as_tuple=False)  # sorted by row
    counts = torch.bincount(nz[:, 0], minlength=N)
    offsets = torch.zeros(N, dtype=torch.long)
    offsets[1:] = counts.cumsum(0)[:-1]
    flat_idx = group[nz[:, 0]] * I + nz[:, 1]
    return torch.nn.functional.embedding_bag(flat_idx, table.reshape(G * I, O), offsets, mode="sum")


# ------------------------------------------------------------------ binary rows by their active units
def active_units(x: torch.Tensor) -> torch.Tensor:
    """Binary rows ``(..., n)`` (bool, or 0/1 values) -> the indices of their active units ``(..., D)``
    (int16, ascending, -1 pads a row with fewer than ``D`` active units; ``D`` the most any row has);
    a ValueError unless ``x`` is bool or 0/1. One pass over ``x`` to find its non-zero units, the 0/1
    check reads those alone."""
    n = x.shape[-1]
    if n > torch.iinfo(torch.int16).max:
        raise ValueError(f"maps of {n} units do not fit int16 indices")
    flat = x.reshape(-1, n)
    rows, units = flat.nonzero(as_tuple=True)  # by row, then unit: each row's units in increasing order
    if x.dtype != torch.bool and not bool((flat[rows, units] == 1).all()):
        raise ValueError("active units are defined for 0/1 rows only")
    counts = torch.bincount(rows, minlength=flat.shape[0])
    D = int(counts.max()) if counts.numel() else 0
    slot = torch.arange(rows.numel()) - (torch.cumsum(counts, 0) - counts)[rows]
    idx = torch.full((flat.shape[0], D), -1, dtype=torch.int16)
    idx[rows, slot] = units.to(torch.int16)
    return idx.reshape(*x.shape[:-1], D)


class ActiveRows:
    """A sequence of binary rows of ``n`` units given by their active units: ``index`` ``(P, T, D)``
    (ascending within a row, -1 pads at its end, as :func:`active_units` gives them). Row ``t`` of
    participant ``p`` is the 0/1 map with ones at ``index[p, t]``. A learning form that reads the
    active units (``delta_binary``) uses the index; any other form the dense rows (:meth:`rows`)."""

    def __init__(self, index: torch.Tensor, n: int, dtype: torch.dtype = torch.float32) -> None:
        if index.dim() != 3 or index.is_floating_point():
            raise ValueError(f"ActiveRows: an integer index (P, T, D), got {tuple(index.shape)} {index.dtype}")
        if index.numel() and (int(index.max()) >= n or int(index.min()) < -1):
            raise ValueError(f"ActiveRows: unit indices must lie in [0, {n}) (-1 pads)")
        a, b = index[..., :-1], index[..., 1:]
        if not bool(((b > a) | (b < 0)).all()) or bool(((a < 0) & (b >= 0)).any()):
            raise ValueError("ActiveRows: each row's units must ascend, the -1 pads at its end")
        self.index, self.n, self.dtype = index, int(n), dtype

    @classmethod
    def of(cls, x: torch.Tensor) -> "ActiveRows":
        """The active units of binary rows ``x`` ``(P, T, n)`` (bool or 0/1; a ValueError otherwise)."""
        return cls(active_units(x), x.shape[-1], x.dtype if x.is_floating_point() else torch.float32)

    width = property(lambda self: self.n)
    length = property(lambda self: self.index.shape[1])
    participants = property(lambda self: self.index.shape[0])

    def to(self, dtype: torch.dtype) -> "ActiveRows":
        """The same rows, read densely in ``dtype``."""
        return self if dtype == self.dtype else ActiveRows(self.index, self.n, dtype)

    def rows(self, lo: int, hi: int) -> torch.Tensor:
        """Steps ``lo..hi`` of every participant as 0/1 rows ``(P, hi - lo, n)``."""
        idx = self.index[:, lo:hi].long()
        out = torch.zeros(*idx.shape[:-1], self.n + 1, dtype=self.dtype)  # column n takes the -1 pads
        out.scatter_(-1, torch.where(idx < 0, self.n, idx), 1.0)
        return out[..., :self.n]

    def select(self, keep: torch.Tensor) -> "ActiveRows":
        """The rows where ``keep`` ``(P, T)`` is True, in their order, per participant; the shorter
        sequences padded at the end with empty rows (no active unit)."""
        per = keep.sum(1)
        L = int(per.max()) if per.numel() else 0
        out = torch.full((self.participants, L, self.index.shape[2]), -1, dtype=self.index.dtype)
        p, t = keep.nonzero(as_tuple=True)
        out[p, keep.long().cumsum(1)[p, t] - 1] = self.index[p, t]
        return ActiveRows(out, self.n, self.dtype)


# ------------------------------------------------------------------ packed binary rows
# A binary map of n units is held as ceil(n / 64) int64 words (8 bits per byte, bytes in the
# machine's order): 32x32 maps take 16 words instead of 1024 floats, so the rows of a trial batch
# are copied, compared and counted in a few bytes each. Packing and unpacking are exact.
_BIT = 2 ** torch.arange(8, dtype=torch.uint8)  # the value of bit k of a byte
_POPCOUNT = torch.tensor([bin(v).count("1") for v in range(256)], dtype=torch.int64)


def pack_bits(x: torch.Tensor) -> torch.Tensor:
    """Binary rows ``(..., n)`` (bool or 0/1 values, a unit is on when above 0.5) packed into
    int64 words ``(..., ceil(n / 64))``."""
    on = x if x.dtype == torch.bool else x > 0.5
    n = on.shape[-1]
    pad = -n % 64
    if pad:
        on = torch.nn.functional.pad(on, (0, pad))
    if on.device.type == "cpu":  # numpy's packing: the same bytes (bit k of a byte = its k-th unit)
        return torch.from_numpy(np.packbits(on.numpy(), axis=-1, bitorder="little")).view(torch.int64)
    lead = on.shape[:-1]
    b = (on.reshape(*lead, -1, 8).to(torch.uint8) * _BIT.to(on.device)).sum(-1, dtype=torch.uint8)
    return b.contiguous().view(torch.int64)


def unpack_bits(words: torch.Tensor, n: int) -> torch.Tensor:
    """The bool rows ``(..., n)`` that :func:`pack_bits` packed into ``words``."""
    b = words.contiguous().view(torch.uint8)
    if b.device.type == "cpu":
        on = torch.from_numpy(np.unpackbits(b.numpy(), axis=-1, bitorder="little")).view(torch.bool)
        return on[..., :n]
    on = (b.unsqueeze(-1) & _BIT.to(b.device)) != 0
    return on.reshape(*words.shape[:-1], -1)[..., :n]


def popcount(words: torch.Tensor) -> torch.Tensor:
    """Number of units on in each packed row ``(..., words)`` -> int64 ``(...)``."""
    if words.device.type == "cpu":
        w = words.contiguous().numpy().view(np.uint64)
        return torch.from_numpy(np.bitwise_count(w).sum(-1, dtype=np.int64))
    return _POPCOUNT.to(words.device)[words.contiguous().view(torch.uint8).long()].sum(-1)


_HASH: dict[int, torch.Tensor] = {}  # random float64 weights per key width (the grouping hash)


def _hash_weights(width: int) -> torch.Tensor:
    if width not in _HASH:
        _HASH[width] = torch.rand(width, generator=torch.Generator().manual_seed(width), dtype=torch.float64) + 0.5
    return _HASH[width]


def unique_rows(group: torch.Tensor, words: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Distinct ``(group, packed row)`` pairs of a batch: ``(groups (U,), words (U, W), inverse (N,))``
    with ``words[i] == unique_words[inverse[i]]`` and ``group[i] == unique_groups[inverse[i]]``. A
    product that depends only on the pair is then computed once per pair and indexed back with
    ``inverse``.

    The rows are grouped by a hash (a random projection of their 32-bit halves) and every group is
    then checked row by row against one of its members; should two different rows ever share a
    hash, the exact ``torch.unique(dim=0)`` grouping is used instead. Either way a group holds only
    equal rows, so what is computed per group does not depend on the hash. The distinct pairs come
    in ascending order of group.
    """
    key = torch.cat([group.reshape(-1, 1).to(torch.int64), words.to(torch.int64)], dim=1).contiguous()
    if len(key):
        halves = key.view(torch.int32).to(torch.float64)
        h = halves @ _hash_weights(halves.shape[1]).to(halves.device)
        _, inverse = torch.unique(h, return_inverse=True)
        rep = torch.zeros(int(inverse.max()) + 1, dtype=torch.long, device=key.device)
        rep.scatter_(0, inverse, torch.arange(len(key), device=key.device))  # one member of each group
        uniq = key[rep]
        if torch.equal(uniq[inverse], key):
            # groups in ascending order, as the exact grouping gives them: the rows of one weight
            # matrix then follow each other (a product over a table of matrices stays in cache)
            order = torch.sort(uniq[:, 0], stable=True).indices
            rank = torch.empty_like(order)
            rank[order] = torch.arange(len(order), device=order.device)
            uniq = uniq[order]
            return uniq[:, 0], uniq[:, 1:], rank[inverse]
    uniq, inverse = torch.unique(key, dim=0, return_inverse=True)
    return uniq[:, 0], uniq[:, 1:], inverse
