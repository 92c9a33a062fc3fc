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


def binary_matmul_rows(table: torch.Tensor, group: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """``W_g x`` for a flat batch of binary rows ``x`` ``(N, in)``, each with its own weight matrix.

    ``table`` ``(G, in, out)`` holds the transposed weights of ``G`` matrices (for instance one per
    participant and forward model) and ``group`` ``(N,)`` says which one each row uses. Like
    :func:`binary_matmul`, the cost grows with the number of active input units.
    """
    G, I, O = table.shape
    N = x.shape[0]
    nz = (x > 0.5).nonzero(as_tuple=False)  # sorted by row
    counts = torch.bincount(nz[:, 0], minlength=N)
    offsets = torch.zeros(N, dtype=torch.long)
    offsets[1:] = counts.cumsum(0)[:-1]
    flat_idx = group[nz[:, 0]] * I + nz[:, 1]
    return torch.nn.functional.embedding_bag(flat_idx, table.reshape(G * I, O), offsets, mode="sum")
