"""Connections with local receptive fields between two maps on the same 3-D grid.

Output unit ``o`` (a voxel of a ``G x G x G`` map) reads only the input voxels ``o + d`` for the
lattice offsets ``d`` with ``|d| <= radius``; the weights are stored as ``(P, n, K)``, one row of
``K`` offsets per output voxel and participant, instead of the dense ``(P, n, n)``. Input voxels
outside the grid read as zero. ``offset_set`` replaces the ball by any set of offsets ``(K, 3)``
in (z, y, x) order (e.g. a column along the line of sight). A local connection is the dense all-to-all connection of eq. 4.4
with every weight outside the receptive fields fixed at zero.

Learning goes through :meth:`LocalConnection.learn` with a :class:`~neuroimagery.nn.rules.Delta`
rule (eq. 6.4): ``dw[o, k] = eta (target_o - post_o) pre_{o + d_k}``, the dense rule restricted to
the stored weights. For binary input (0/1, the 3-D dot images and voxel maps) only the weights of
the active inputs are read and written; both the product and the update add in index order
(``index_add_`` on the CPU), so the numbers do not depend on the thread count.
"""
from __future__ import annotations

import math
from typing import Sequence

import torch

from . import seeding
from .connections import Connection
from .functional import check_floating
from .rules import Delta, Rule


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
        for r in self.rules:
            if not isinstance(r, Delta):
                raise ValueError(f"LocalConnection {name!r}: only the delta rule is implemented, got {type(r).__name__}")
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
    def net(self, x: torch.Tensor) -> torch.Tensor:
        """``W x`` for any input ``(P, B, n)``: gathers each output's receptive field."""
        if x.dim() != 3 or x.shape[-1] != self.n_in or x.shape[0] != self.participants:
            raise ValueError(f"connection {self.name!r}: input must be ({self.participants}, B, {self.n_in}), got {tuple(x.shape)}")
        check_floating(f"input of connection {self.name!r}", x)
        w = self.weight if self.weight.dtype == x.dtype else self.weight.to(x.dtype)  # in the input's dtype
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
        r, i = (x != 0).nonzero(as_tuple=True)  # sorted by row, then input voxel
        out = torch.zeros(N * (n + 1), dtype=self.weight.dtype)
        if r.numel():
            o = self.target_of[i]  # (A, K) output voxel each active input reaches through offset k
            k = torch.arange(self.K).expand_as(o)
            w = self.weight[group[r].unsqueeze(1), o.clamp_max(n - 1), k]  # (A, K)
            w = torch.where(o < n, w * x[r, i].unsqueeze(1).to(w.dtype), torch.zeros_like(w))
            out.index_add_(0, (r.unsqueeze(1) * (n + 1) + o).reshape(-1), w.reshape(-1))
        return out.view(N, n + 1)[:, :n]

    def net_rows(self, x: torch.Tensor, group: torch.Tensor) -> torch.Tensor:
        """``W x`` for any input rows ``(N, n)``, row r using participant ``group[r]`` (the sparse
        path when at most a quarter of the units are active)."""
        N, n = x.shape
        if N and float((x != 0).float().mean()) <= 0.25:
            return self.net_binary(x, group)
        pad = torch.cat([x, x.new_zeros(N, 1)], -1)
        out = x.new_zeros(N, n)
        for k in range(self.K):
            out += pad[:, self.source[:, k]] * self.weight[group, :, k]
        return out

    # ------------------------------------------------------------------ learning
    def _offset(self, src: torch.Tensor, out: torch.Tensor) -> torch.Tensor:
        """Offset index k with ``source[out, k] == src`` (elementwise), -1 when ``src`` is outside
        ``out``'s receptive field."""
        side, span = self.side, 2 * self.side - 1
        dz = self.coords[src] - self.coords[out] + side - 1
        return self.offset_of[(dz[..., 0] * span + dz[..., 1]) * span + dz[..., 2]]

    @torch.no_grad()
    def _learn_index(self, pre_index: torch.Tensor, target_index: torch.Tensor, scale: float) -> torch.Tensor:
        """The delta rule for binary patterns given by their active units: ``pre_index`` ``(P, B, D)``,
        ``target_index`` ``(P, B, T)`` (-1 = no unit; repeats count once, as in a 0/1 map). Returns
        the flat weight indices and changes (``index_add_`` order = pattern order)."""
        P, B, D = pre_index.shape
        n, K = self.n_in, self.K
        pre = pre_index.reshape(P * B, D)
        # a repeated active unit counts once (0/1 input)
        dup = torch.zeros_like(pre, dtype=torch.bool)
        for d in range(1, D):
            dup[:, d] = (pre[:, :d] == pre[:, d:d + 1]).any(-1)
        valid = (pre >= 0) & ~dup
        safe = pre.clamp_min(0)
        o = self.target_of[safe]  # (R, D, K) outputs reached
        ok = valid.unsqueeze(-1) & (o < n)
        oc = o.clamp_max(n - 1)
        part = torch.arange(P).repeat_interleave(B)  # (R,)
        k = torch.arange(K).view(1, 1, K).expand_as(oc)
        flat = (part.view(-1, 1, 1) * n + oc) * K + k  # (R, D, K) weight of each reached output from its own unit
        wv = self.weight.view(-1)
        post = wv[flat]  # the unit's own contribution
        # contributions of the pattern's other active units: only those within twice the radius matter
        c = self.coords[safe]  # (R, D, 3)
        for d in range(D):
            for d2 in range(D):
                if d2 == d:
                    continue
                near = valid[:, d] & valid[:, d2] & ((c[:, d] - c[:, d2]).abs().max(-1).values <= 2 * self.radius)
                r = near.nonzero().squeeze(-1)
                if r.numel() == 0:
                    continue
                oo = oc[r, d]  # (r, K)
                k2 = self._offset(safe[r, d2].unsqueeze(-1).expand_as(oo), oo)
                w = wv[((part[r].unsqueeze(-1) * n + oo) * K + k2.clamp_min(0))]
                post[r, d] += torch.where(ok[r, d] & (k2 >= 0), w, torch.zeros_like(w))
        tgt = target_index.reshape(P * B, -1)
        hit = (oc.unsqueeze(-1) == tgt.view(P * B, 1, 1, -1)).any(-1)  # (R, D, K)
        err = hit.to(post.dtype) - post
        return flat.reshape(-1), torch.where(ok, scale * err, torch.zeros_like(err)).reshape(-1)

    @torch.no_grad()
    def learn(self, pre: torch.Tensor | None = None, post: torch.Tensor | None = None, return_delta: bool = False,
              target: torch.Tensor | None = None, pre_index: torch.Tensor | None = None,
              target_index: torch.Tensor | None = None, **kw) -> torch.Tensor | None:
        """The delta rule (eq. 6.4) on the stored weights, summed over the batch.

        Dense form: ``pre`` ``(P, B, n)``, ``post`` the output at the current weights (computed here
        when None), ``target`` ``(P, B, n)``; binary ``pre`` takes a sparse path. Index form, for
        binary patterns: ``pre_index`` ``(P, B, D)`` and ``target_index`` ``(P, B, T)`` list the
        active units (-1 = none); the same rule without forming the maps. Only in ``train()`` mode
        and with a rule attached (the first call in ``eval()`` mode warns)."""
        if not self.learning():
            return None
        if pre_index is not None:
            if target_index is None:
                raise ValueError(f"connection {self.name!r}: the index form needs target_index")
            total = torch.zeros_like(self.weight) if return_delta or len(self.rules) > 1 else None
            for rule in self.rules:
                scale = rule.eta / pre_index.shape[1] if rule.reduction == "mean" else rule.eta
                flat, delta = self._learn_index(pre_index, target_index, scale)
                (self.weight if total is None else total).view(-1).index_add_(0, flat, delta)
            if total is not None:
                self.weight.add_(total)
            return total
        if pre is None:
            raise ValueError(f"connection {self.name!r}: learn needs pre or pre_index")
        if target is None:
            raise ValueError(f"connection {self.name!r}: the delta rule needs a target")
        # the change in the weights' dtype, so they keep it
        pre, target = (check_floating(f"{what} of connection {self.name!r}", x).to(self.weight.dtype)
                       for what, x in (("pre", pre), ("target", target)))
        post = None if post is None else post.to(self.weight.dtype)
        P, B, n = pre.shape
        binary = bool(((pre == 0) | (pre == 1)).all()) or float((pre != 0).float().mean()) <= 0.25  # the sparse path
        if post is None:
            post = self.net_binary(pre.reshape(P * B, n), torch.arange(P).repeat_interleave(B)).view(P, B, n) \
                if binary else self.net(pre)
        err = target - post  # (P, B, n)
        total = torch.zeros_like(self.weight) if return_delta or len(self.rules) > 1 else None
        for rule in self.rules:
            scale = rule.eta / B if rule.reduction == "mean" else rule.eta
            if binary:
                p, b, i = (pre != 0).nonzero(as_tuple=True)
                o = self.target_of[i]  # (A, K)
                k = torch.arange(self.K).expand_as(o)
                e = torch.cat([err, err.new_zeros(P, B, 1)], -1)[p.unsqueeze(1), b.unsqueeze(1), o]  # (A, K)
                e = e * pre[p, b, i].unsqueeze(1)  # graded input: the rule's pre factor
                flat = ((p.unsqueeze(1) * n + o.clamp_max(n - 1)) * self.K + k)
                delta = torch.where(o < n, scale * e, torch.zeros_like(e))
                if total is None:
                    self.weight.view(-1).index_add_(0, flat.reshape(-1), delta.reshape(-1))
                else:
                    total.view(-1).index_add_(0, flat.reshape(-1), delta.reshape(-1))
            else:
                pad = torch.cat([pre, pre.new_zeros(P, B, 1)], -1)
                d = torch.stack([(err * pad[..., self.source[:, k]]).sum(1) for k in range(self.K)], -1) * scale
                d = d * (self.source < n).unsqueeze(0)
                if total is None:
                    self.weight.add_(d)
                else:
                    total.add_(d)
        if total is not None:
            self.weight.add_(total)
        return total

    def dense(self, participant: int = 0) -> torch.Tensor:
        """The equivalent dense weight matrix ``(n, n)`` of one participant (for checks)."""
        n = self.n_in
        W = torch.zeros(n, n + 1, dtype=self.weight.dtype)
        W.scatter_add_(1, self.source, self.weight[participant])
        return W[:, :n]

    def extra_repr(self) -> str:
        return f"name={self.name!r}, side={self.side}, radius={self.radius}, K={self.K}, P={self.participants}"
