"""Products of weights with binary (0/1) activity, computed as sums of the weight rows of the active
units: the cost grows with the number of active units (edge pixels), not with the map size. The
forward models of Experiments 3 and 4 read their 32x32 edge maps this way."""
from __future__ import annotations

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
    lead = on.shape[:-1]
    b = (on.reshape(*lead, -1, 8).to(torch.uint8) * _BIT.to(on.device)).sum(-1, dtype=torch.uint8)
    return b.contiguous().view(torch.int64)


def unpack_bits(words: torch.Tensor, n: int) -> torch.Tensor:
    """The bool rows ``(..., n)`` that :func:`pack_bits` packed into ``words``."""
    b = words.contiguous().view(torch.uint8)
    on = (b.unsqueeze(-1) & _BIT.to(b.device)) != 0
    return on.reshape(*words.shape[:-1], -1)[..., :n]


def popcount(words: torch.Tensor) -> torch.Tensor:
    """Number of units on in each packed row ``(..., words)`` -> int64 ``(...)``."""
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
