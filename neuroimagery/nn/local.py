"""Connections with local receptive fields between two maps on the same 3-D grid.

Output unit ``o`` (a voxel of a ``G x G x G`` map) reads only the input voxels ``o + d`` for the
lattice offsets ``d`` with ``|d| <= radius``; the weights are stored as ``(P, n, K)``, one row of
``K`` offsets per output voxel and participant, instead of the dense ``(P, n, n)``. Input voxels
outside the grid read as zero. ``offset_set`` replaces the ball by any set of offsets ``(K, 3)``
in (z, y, x) order (e.g. a column along the line of sight). A local connection is the dense all-to-all connection of eq. 4.4
with every weight outside the receptive fields fixed at zero.

Learning goes through :meth:`LocalConnection.learn`, which applies each attached rule by the form
registered for it and a local connection (:mod:`.forms`): the delta rule (eq. 6.4) has its own
(:mod:`.delta`: ``dw[o, k] = eta (target_o - post_o) pre_{o + d_k}``, from active-unit indices,
sparse or dense activity); any other rule takes :class:`Restricted`, its change on the equivalent
dense weights kept at the stored ones. The sparse product adds in index order (``index_add_`` on
the CPU), so the numbers do not depend on the thread count.
"""
from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Sequence

import torch

from . import forms, local_kernel, seeding
from .change import as_change
from .connections import Connection
from .forms import Form, register
from .functional import check_floating
from .rules import Rule


def offsets(radius: float) -> torch.Tensor:
    """Integer 3-D offsets ``(K, 3)`` with length <= ``radius``, sorted (z, y, x) lexicographically."""
    r = int(math.floor(radius))
    rng = torch.arange(-r, r + 1)
    d = torch.stack(torch.meshgrid(rng, rng, rng, indexing="ij"), -1).reshape(-1, 3)
    return d[(d.float() ** 2).sum(-1) <= radius * radius + 1e-9]


def offset_count(radius: float) -> int:
    return int(offsets(radius).shape[0])


class LocalConnection(Connection):
    """A local-receptive-field connection on a ``side^3`` grid (see the module docstring).

    ``init=(low, high)``: U[low, high) initial weights per participant (only the stored ones);
    ``generators`` one per participant.
    """

    def __init__(self, side: int, radius: float, generators: Sequence[torch.Generator],
                 init: tuple[float, float] = (0.0, 0.01), rules: Rule | Sequence[Rule] = (), name: str = "",
                 offset_set: torch.Tensor | None = None) -> None:
        n = side ** 3
        d = offsets(radius) if offset_set is None else torch.as_tensor(offset_set, dtype=torch.long).reshape(-1, 3)
        if offset_set is not None:  # any receptive-field shape: ``radius`` becomes the longest offset
            radius = float((d.float() ** 2).sum(-1).sqrt().max())
        K = d.shape[0]
        w = seeding.uniform(generators, (n, K), float(init[0]), float(init[1]))
        # weight buffer (P, n, K); Connection's dense helpers are replaced below
        super().__init__(n, n, w, "identity", rules, name)
        self.side, self.radius, self.K = int(side), float(radius), int(K)
        z, y, x = torch.meshgrid(torch.arange(side), torch.arange(side), torch.arange(side), indexing="ij")
        coords = torch.stack([z, y, x], -1).reshape(-1, 3)  # voxel o = (z * side + y) * side + x
        src = coords.unsqueeze(1) + d.unsqueeze(0)  # (n, K, 3) input voxel of each stored weight
        ok = ((src >= 0) & (src < side)).all(-1)
        flat = (src[..., 0] * side + src[..., 1]) * side + src[..., 2]
        self.register_buffer("source", torch.where(ok, flat, torch.full_like(flat, n)))  # n = zero pad
        # the mask zeroes weights whose input lies outside the grid (they never act)
        self.weight.mul_(ok.unsqueeze(0).to(self.weight.dtype))
        # for each input voxel i and offset k, the output o with source[o, k] == i (or n when outside)
        dst = coords.unsqueeze(1) - d.unsqueeze(0)
        okd = ((dst >= 0) & (dst < side)).all(-1)
        flat_d = (dst[..., 0] * side + dst[..., 1]) * side + dst[..., 2]
        self.register_buffer("target_of", torch.where(okd, flat_d, torch.full_like(flat_d, n)))
        # offset index of any coordinate difference (source - output), -1 outside the receptive field
        span = 2 * side - 1
        lut = torch.full((span ** 3,), -1, dtype=torch.long)
        lut[((d[:, 0] + side - 1) * span + d[:, 1] + side - 1) * span + d[:, 2] + side - 1] = torch.arange(K)
        self.register_buffer("offset_of", lut, persistent=False)
        self.register_buffer("coords", coords, persistent=False)

    # ------------------------------------------------------------------ products
    def net(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """``W x`` for any input ``(P, B, n)``: gathers each output's receptive field (its shape is
        checked at every call; ``checked`` is accepted for the interface of :meth:`Connection.net`)."""
        if x.dim() != 3 or x.shape[-1] != self.n_in or x.shape[0] != self.participants:
            raise ValueError(f"connection {self.name!r}: input must be ({self.participants}, B, {self.n_in}), got {tuple(x.shape)}")
        check_floating(f"input of connection {self.name!r}", x)
        w = self.weight if self.weight.dtype == x.dtype else self.weight.to(x.dtype)  # in the input's dtype
        if local_kernel.available(w, x):
            P, B, n = x.shape
            group = torch.arange(P).repeat_interleave(B)
            return local_kernel.net_dense(w, self.source, x.reshape(P * B, n), group).view(P, B, n)
        pad = torch.cat([x, x.new_zeros(*x.shape[:-1], 1)], -1)  # (P, B, n + 1)
        out = x.new_zeros(x.shape)
        for k in range(self.K):  # one offset at a time keeps the memory at (P, B, n)
            out += pad[..., self.source[:, k]] * w[:, :, k].unsqueeze(1)
        return out

    def net_binary(self, x: torch.Tensor, group: torch.Tensor | None = None) -> torch.Tensor:
        """``W x`` for sparse ``x`` ``(N, n)`` rows (binary, or graded with few active units), row r
        using participant ``group[r]`` (default: all rows of participant 0 when P == 1). Cost grows
        with the active voxels, not the grid."""
        N, n = x.shape
        if group is None:
            if self.participants != 1:
                raise ValueError("net_binary: give the participant of each row")
            group = torch.zeros(N, dtype=torch.long)
        if local_kernel.available(self.weight, x.to(self.weight.dtype)):
            return local_kernel.net_sparse(self.weight, self.target_of, x.to(self.weight.dtype), group)
        r, i = (x != 0).nonzero(as_tuple=True)  # sorted by row, then input voxel
        out = torch.zeros(N * (n + 1), dtype=self.weight.dtype)
        if r.numel():
            o = self.target_of[i]  # (A, K) output voxel each active input reaches through offset k
            k = torch.arange(self.K).expand_as(o)
            w = self.weight[group[r].unsqueeze(1), o.clamp_max(n - 1), k]  # (A, K)
            w = torch.where(o < n, w * x[r, i].unsqueeze(1).to(w.dtype), torch.zeros_like(w))
            out.index_add_(0, (r.unsqueeze(1) * (n + 1) + o).reshape(-1), w.reshape(-1))
        return out.view(N, n + 1)[:, :n]

    def transposed(self, *_, **__) -> torch.Tensor:
        raise TypeError(f"connection {self.name!r} stores receptive fields (P, n, K), not a dense W^T: "
                        "use net, net_binary or net_rows")

    net_sparse = net_of = net_reverse = incoming = transposed

    def net_rows(self, x: torch.Tensor, group: torch.Tensor) -> torch.Tensor:
        """``W x`` for any input rows ``(N, n)``, row r using participant ``group[r]`` (the sparse
        path when at most a quarter of the units are active)."""
        N, n = x.shape
        if N and float((x != 0).float().mean()) <= 0.25:
            return self.net_binary(x, group)
        if local_kernel.available(self.weight, x):
            return local_kernel.net_dense(self.weight, self.source, x, group)
        pad = torch.cat([x, x.new_zeros(N, 1)], -1)
        out = x.new_zeros(N, n)
        for k in range(self.K):
            out += pad[:, self.source[:, k]] * self.weight[group, :, k]
        return out

    # ------------------------------------------------------------------ learning
    def offset_index(self, src: torch.Tensor, out: torch.Tensor) -> torch.Tensor:
        """Offset index k with ``source[out, k] == src`` (elementwise), -1 when ``src`` is outside
        ``out``'s receptive field."""
        side, span = self.side, 2 * self.side - 1
        dz = self.coords[src] - self.coords[out] + side - 1
        return self.offset_of[(dz[..., 0] * span + dz[..., 1]) * span + dz[..., 2]]

    @torch.no_grad()
    def learn(self, pre: torch.Tensor | None = None, post: torch.Tensor | None = None, return_delta: bool = False,
              **kw) -> torch.Tensor | None:
        """Every rule's change to the stored weights, each computed at the same weights, by the
        form registered for the rule and a local connection (:mod:`.forms`).

        ``pre`` ``(P, B, n)`` and ``post`` (the delta rule computes the output at the current
        weights when None), and the rule's own arguments (the delta rule's ``target``
        ``(P, B, n)``; or, for binary patterns, ``pre_index`` ``(P, B, D)`` and ``target_index``
        ``(P, B, T)`` listing the active units, -1 = none). Only in ``train()`` mode and with a
        rule attached (the first call in ``eval()`` mode warns). Returns the summed change when
        ``return_delta`` or several rules ask for it, else None."""
        if not self.learning():
            return None
        if pre is None and kw.get("pre_index") is None:
            raise ValueError(f"connection {self.name!r}: learn needs pre or pre_index")
        # the change in the weights' dtype, so they keep it
        if pre is not None:
            pre = check_floating(f"pre of connection {self.name!r}", pre).to(self.weight.dtype)
        if kw.get("target") is not None:
            kw["target"] = check_floating(f"target of connection {self.name!r}", kw["target"]).to(self.weight.dtype)
        post = None if post is None else post.to(self.weight.dtype)
        total = torch.zeros_like(self.weight) if return_delta or len(self.rules) > 1 else None
        call = SimpleNamespace(pre=pre, post=post, kw=kw, out=self.weight if total is None else total)
        for rule in self.rules:
            form = forms.choose(self, rule, call)
            if form is None:
                raise ValueError(f"connection {self.name!r}: no form of {type(rule).__name__} takes these inputs")
            form.run(self, rule, call)
        if total is not None:
            self.weight.add_(total)
        return total

    def restrict(self, change: torch.Tensor) -> torch.Tensor:
        """A dense change ``(P, n, n)`` at the stored weights ``(P, n, K)`` (zero outside the grid)."""
        P, n = change.shape[0], self.n_in
        pad = torch.cat([change, change.new_zeros(P, n, 1)], -1)
        return pad.gather(2, self.source.unsqueeze(0).expand(P, -1, -1))

    def dense(self, participant: int = 0) -> torch.Tensor:
        """The equivalent dense weight matrix ``(n, n)`` of one participant (for checks)."""
        n = self.n_in
        W = torch.zeros(n, n + 1, dtype=self.weight.dtype)
        W.scatter_add_(1, self.source, self.weight[participant])
        return W[:, :n]

    def extra_repr(self) -> str:
        return f"name={self.name!r}, side={self.side}, radius={self.radius}, K={self.K}, P={self.participants}"


@register(Rule, LocalConnection)
class Restricted(Form):
    """Any rule on a local connection: its change on the equivalent dense weights ``(P, n, n)``
    (:meth:`LocalConnection.dense`), kept at the stored weights. A local connection is the dense
    one with every weight outside the receptive fields fixed at zero, so the change of a weight is
    the dense rule's wherever that rule's change of a weight depends on that weight and the
    activity alone. Costs ``n x n`` per participant: rules used at scale register their own form."""

    name, priority = "restricted", 99

    def why_not(self, conn, rule, call):
        return None if call.pre is not None and call.kw.get("pre_index") is None else "needs pre"

    @torch.no_grad()
    def run(self, conn, rule, call) -> None:
        W = torch.stack([conn.dense(p) for p in range(conn.participants)])
        kw = {k: v for k, v in call.kw.items() if v is not None}
        call.out.add_(conn.restrict(as_change(W, rule.delta(W, pre=call.pre, post=call.post, **kw)).tensor()))
