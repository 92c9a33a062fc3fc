"""The fast read-outs of a block's weights ``(P, out, in)`` (a connection's or a SOM's), for the
inner loops of the models: the block checks an input's shape, dtype and participants once per
configuration (the last one it saw) and its values once per call unless the caller has checked
the batch (``checked=True``); products of sparse and binary activity use the block's transposed
weights, kept while the weights stay the same (:meth:`Readouts.weights_version`).

* :meth:`Readouts.net_binary`, :meth:`Readouts.net_sparse`: ``W x`` as the sum of the weight rows
  of the active inputs (:mod:`.binary`), exactly ``W x`` for 0/1 inputs;
* :meth:`Readouts.net_of`: one participant's ``W x`` for one pattern or a few rows (the
  matrix-vector product a plain, one-trial-at-a-time reference computes);
* :meth:`Readouts.net_reverse`: ``W^T y``, the block read from its outputs back to its inputs;
* :meth:`Readouts.incoming`: the weights into one output unit (a receptive field, for a figure);
* :func:`binary_rows`: rows of several blocks of one shape at once (row ``r`` by block
  ``group[r] % len(blocks)`` of participant ``group[r] // len(blocks)``), each block from its own
  transposed weights.
"""
from __future__ import annotations

from typing import Sequence

import torch

from .binary import binary_matmul, binary_matmul_rows, sparse_matmul
from .functional import as_batched_shape, check_floating, check_participants, check_tensor, checks_enabled, transposed_copy


class Readouts:
    """Mixed into a block with a ``weight`` buffer ``(P, out, in)`` and a ``name``."""

    _table_cache: tuple | None = None
    _config: tuple | None = None  # the input configuration checked last (shape, dtype, device)

    def weights_version(self) -> tuple[int, int]:
        """Changes whenever the weights change, in place (learning, loading) or replaced (``to()``)."""
        return (self.weight.data_ptr(), self.weight._version)

    def transposed(self) -> torch.Tensor:
        """``W^T`` ``(P, in, out)``, contiguous, made once per version of the weights."""
        key = self.weights_version()
        if self._table_cache is None or self._table_cache[0] != key:
            self._table_cache = (key, transposed_copy(self.weight))
        return self._table_cache[1]

    def keep_transposed(self, table: torch.Tensor) -> None:
        """Keep ``table``, which must equal ``W^T`` ``(P, in, out)`` of the present weights (a form
        that trained the weights transposed hands them over), as :meth:`transposed`'s copy."""
        if table.shape != (self.weight.shape[0], self.weight.shape[2], self.weight.shape[1]) or not table.is_contiguous():
            raise ValueError(f"keep_transposed of {self.block_name()}: a contiguous (P, in, out) table, got {tuple(table.shape)}")
        self._table_cache = (self.weights_version(), table)

    def batched(self, x: torch.Tensor, n: int, checked: bool = False) -> tuple[torch.Tensor, bool]:
        """``x`` as ``(P, B, n)`` and whether to squeeze the participant axis again: shape, dtype
        and participants checked once per configuration, the values unless ``checked`` (the
        caller has checked the batch)."""
        config = (x.shape, x.dtype, x.device, n, self.participants) if isinstance(x, torch.Tensor) else None
        if config is None or config != self._config:
            what = f"input of {self.block_name()}"
            check_tensor(what, x, (n,), finite=not checked)
            xb, squeeze = as_batched_shape(x, n, what)
            check_participants(self.block_name(), self.participants, xb, x.shape)
            self._config = config
            return xb, squeeze
        if not checked and x.is_floating_point() and checks_enabled(x) and not torch.isfinite(x).all():
            raise ValueError(f"input of {self.block_name()} contains NaN or infinite values")
        if x.dim() == 3:
            return x, False
        return (x.reshape(1, 1, n) if x.dim() == 1 else x.unsqueeze(0)), True

    block_kind = "block"

    def block_name(self) -> str:
        return f"{self.block_kind} {self.name!r}"

    def _rows_input(self, x: torch.Tensor, what: str) -> None:
        if x.dim() != 3 or x.shape[0] != self.participants or x.shape[-1] != self.weight.shape[2]:
            raise ValueError(f"{what} of {self.block_name()}: input must be ({self.participants}, B, "
                             f"{self.weight.shape[2]}), got {tuple(x.shape)}")

    def net_binary(self, x: torch.Tensor, group: torch.Tensor | None = None) -> torch.Tensor:
        """``W x`` for binary (0/1) ``x`` ``(P, B, in)``, or for rows ``x`` ``(N, in)`` of
        participants ``group`` ``(N,)``: the sum of the weight rows of the active inputs (a unit
        is active above 0.5), the cost growing with the active units, not the map."""
        if group is not None:
            if x.dim() != 2 or group.shape != x.shape[:1]:
                raise ValueError(f"net_binary of {self.block_name()}: rows (N, in) and group (N,), "
                                 f"got {tuple(x.shape)}, {tuple(group.shape)}")
            return binary_matmul_rows(self.transposed(), group, x)
        self._rows_input(x, "net_binary")
        return binary_matmul(self.transposed(), x)

    def net_sparse(self, x: torch.Tensor) -> torch.Tensor:
        """``W x`` for graded, mostly-zero ``x`` ``(P, B, in)``: the weight rows of the non-zero
        inputs, each weighted by its activity."""
        self._rows_input(x, "net_sparse")
        return sparse_matmul(self.transposed(), x)

    def net_of(self, participant: int, x: torch.Tensor) -> torch.Tensor:
        """Participant ``participant``'s ``W x`` for one pattern ``x`` ``(in,)`` -> ``(out,)``, or
        for rows ``(B, in)`` -> ``(B, out)`` (a matrix-vector product for one pattern)."""
        w = self.weight[participant]
        if x.shape[-1] != w.shape[1] or x.dim() not in (1, 2):
            raise ValueError(f"net_of of {self.block_name()}: input (in,) or (B, in) with in={w.shape[1]}, "
                             f"got {tuple(x.shape)}")
        w = w if w.dtype == x.dtype else w.to(x.dtype)
        return w @ x if x.dim() == 1 else x @ w.T

    def net_reverse(self, y: torch.Tensor) -> torch.Tensor:
        """``W^T y`` for activity of the outputs ``y`` ``(P, B, out)`` -> ``(P, B, in)``: the block
        read backwards, from its outputs to its inputs."""
        if y.dim() != 3 or y.shape[0] != self.participants or y.shape[-1] != self.weight.shape[1]:
            raise ValueError(f"net_reverse of {self.block_name()}: output activity must be "
                             f"({self.participants}, B, {self.weight.shape[1]}), got {tuple(y.shape)}")
        check_floating(f"output activity of {self.block_name()}", y)
        w = self.weight if self.weight.dtype == y.dtype else self.weight.to(y.dtype)
        return torch.bmm(y, w)

    def incoming(self, unit: int, participant: int = 0) -> torch.Tensor:
        """A copy of the weights into output ``unit`` of ``participant`` ``(in,)`` (its receptive
        field, e.g. for a figure)."""
        return self.weight[participant, unit].clone()

    @property
    def weights_per_participant(self) -> int:
        """How many weights one participant's copy of the block holds."""
        return self.weight[0].numel()


def binary_rows(blocks: Sequence[Readouts], group: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Rows of several blocks of one shape at once: binary rows ``x`` ``(N, in)``, row ``r`` read
    by block ``group[r] % len(blocks)`` of participant ``group[r] // len(blocks)`` -> ``(N, out)``.
    Each block reads its own rows from its transposed weights (:meth:`Readouts.transposed`, kept
    while its weights stay the same), a row's active weight rows summed in the same order as
    from one table of all the blocks."""
    first = blocks[0]
    if any(b.weight.shape != first.weight.shape for b in blocks):
        raise ValueError("binary_rows: the blocks must have weights of one shape")
    nb = len(blocks)
    which, part = group % nb, group // nb
    out = torch.empty(x.shape[0], first.weight.shape[1], dtype=first.weight.dtype, device=first.weight.device)
    for k, b in enumerate(blocks):
        sel = (which == k).nonzero().squeeze(-1)
        if sel.numel():
            out[sel] = binary_matmul_rows(b.transposed(), part[sel], x[sel])
    return out
