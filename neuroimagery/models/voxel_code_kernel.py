"""The dot maps of :func:`~neuroimagery.models.voxel_code.blobs` compiled with numba, for CPUs: the
same float64 and float32 operations, in the same order, as the torch code of that function, so
the two give the same numbers (``tests/test_exp6_kernels.py`` compares them); only the exponential stays
torch's. A dot's window of ``(2r + 1)^3`` voxels costs its arithmetic instead of a dozen tensors
of ``dots x window`` entries.

Per dot at voxel coordinates ``pos`` (nearest voxel ``near``) and window offset ``(a, b, c)``
(x, y, z): ``arg = -((vx - px)^2 + (vy - py)^2 + (vz - pz)^2) / (2 sigma^2)`` (float64), the
voxel ``(vz G + vy) G + vx`` or none outside the grid (:func:`arguments`); after torch's ``exp``
and the cast to float32, each row's dots added in order, cut to [0, 1], units below ``silent``
zeroed (:func:`scatter`). The largest 26-connected cluster of a binary map
(:func:`largest_cluster`: the sizes of the clusters that spreading labels finds). Without numba
the torch code runs.
"""
from __future__ import annotations

import numpy as np
import torch

from ..nn import compiled


def available() -> bool:
    """Whether the compiled loops can run (numba installed, not while ``torch.compile`` traces)."""
    return compiled.available()


def _arguments(pos, near, t, side, c2, arg, flat):  # pragma: no cover (compiled)
    N, D, _ = pos.shape
    L = t.shape[0]
    n = side * side * side
    for r in range(N):
        for d in range(D):
            px, py, pz = pos[r, d, 0], pos[r, d, 1], pos[r, d, 2]
            w = 0
            for a in range(L):
                vx = near[r, d, 0] + t[a]
                dx = np.float64(vx) - px
                for b in range(L):
                    vy = near[r, d, 1] + t[b]
                    dy = np.float64(vy) - py
                    for c in range(L):
                        vz = near[r, d, 2] + t[c]
                        dz = np.float64(vz) - pz
                        d2 = dx * dx + dy * dy
                        d2 = d2 + dz * dz
                        arg[r, d, w] = (-d2) / c2
                        if 0 <= vx < side and 0 <= vy < side and 0 <= vz < side:
                            flat[r, d, w] = (vz * side + vy) * side + vx
                        else:
                            flat[r, d, w] = n
                        w += 1


def _scatter(val, flat, silent, out):  # pragma: no cover (compiled)
    N, D, W = val.shape
    n = out.shape[1]
    zero, one = np.float32(0.0), np.float32(1.0)
    for r in range(N):
        for d in range(D):
            for w in range(W):
                f = flat[r, d, w]
                if f < n:
                    out[r, f] += val[r, d, w]
        for i in range(n):
            v = min(max(out[r, i], zero), one)
            out[r, i] = v if v >= silent else zero


def _largest(on, side, out):  # pragma: no cover (compiled)
    N, n = on.shape
    seen = np.zeros(n, dtype=np.bool_)
    stack = np.empty(n, dtype=np.int64)
    for r in range(N):
        seen[:] = False
        best = 0
        for v0 in range(n):
            if not on[r, v0] or seen[v0]:
                continue
            seen[v0] = True
            stack[0] = v0
            top, size = 1, 0
            while top > 0:
                top -= 1
                v = stack[top]
                size += 1
                z, y, x = v // (side * side), (v // side) % side, v % side
                for dz in range(-1, 2):
                    zz = z + dz
                    if zz < 0 or zz >= side:
                        continue
                    for dy in range(-1, 2):
                        yy = y + dy
                        if yy < 0 or yy >= side:
                            continue
                        for dx in range(-1, 2):
                            xx = x + dx
                            if xx < 0 or xx >= side:
                                continue
                            u = (zz * side + yy) * side + xx
                            if on[r, u] and not seen[u]:
                                seen[u] = True
                                stack[top] = u
                                top += 1
            best = max(best, size)
        out[r] = best


_fn = compiled.Kernels(globals())  # the compiled loops, each once


def arguments(pos: torch.Tensor, near: torch.Tensor, t: torch.Tensor, side: int, c2: float):
    """``(arg, flat)`` ``(N, D, W)``: each window voxel's exponent (float64) and flat index (``G^3``
    outside the grid), for dots at voxel coordinates ``pos`` ``(N, D, 3)`` (float64, x y z) with
    nearest voxels ``near`` (int64) and window offsets ``t`` per axis."""
    N, D, _ = pos.shape
    W = t.shape[0] ** 3
    arg = torch.empty(N, D, W, dtype=torch.float64)
    flat = torch.empty(N, D, W, dtype=torch.int64)
    _fn("arguments")(pos.contiguous().numpy(), near.contiguous().numpy(), t.contiguous().numpy(), int(side),
                     float(c2), arg.numpy(), flat.numpy())
    return arg, flat


def scatter(val: torch.Tensor, flat: torch.Tensor, n: int, silent: float) -> torch.Tensor:
    """Maps ``(N, n)`` (float32): each row's window values ``val`` ``(N, D, W)`` added at ``flat``,
    cut to [0, 1], units below ``silent`` zeroed."""
    out = torch.zeros(val.shape[0], n, dtype=torch.float32)
    _fn("scatter")(val.contiguous().numpy(), flat.contiguous().numpy(), np.float32(silent), out.numpy())
    return out


def largest_cluster(on: torch.Tensor, side: int) -> torch.Tensor:
    """Voxels ``(N,)`` in the largest 26-connected cluster of each boolean map ``on`` ``(N, G^3)``
    (a search from each voxel not yet reached, instead of spreading labels: the same clusters)."""
    out = torch.zeros(on.shape[0], dtype=torch.int64)
    _fn("largest")(on.contiguous().numpy(), int(side), out.numpy())
    return out
