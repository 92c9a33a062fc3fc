"""The integration loop of :meth:`neuroimagery.motor.dmp.DMP.rollout` compiled with numba, for
float32 rollouts on the CPU: the same float32 operations, in the same order, as the torch loop
(``acc = k (g - y) - c v + f``, ``v <- v + dt acc``, ``y <- y + dt v``, each constant rounded to
float32 as torch rounds a Python number against a float32 tensor, no fused multiply-add), so the
two give the same bits (``tests/test_dmp.py`` compares them); a step costs its arithmetic instead
of eight tensor operations' dispatch. Without numba the torch loop runs.
"""
from __future__ import annotations

import numpy as np
import torch

from ..nn import compiled


def available(*tensors: torch.Tensor) -> bool:
    """Whether the compiled loop can integrate these tensors: numba installed, float32 CPU tensors
    that no gradient flows through, and not while ``torch.compile`` traces (those take the torch loop)."""
    if not compiled.available():
        return False
    grad = torch.is_grad_enabled()
    return all(t.device.type == "cpu" and t.dtype == torch.float32 and not (grad and t.requires_grad) for t in tensors)


def _loop(g, y0, f, k, c, dt, out):
    S, N, J = f.shape
    for n in range(N):
        for j in range(J):
            y = y0[n, j]
            v = np.float32(0.0)
            gj = g[n, j]
            out[n, 0, j] = y
            for s in range(S):
                acc = k * (gj - y) - c * v + f[s, n, j]
                v = v + dt * acc
                y = y + dt * v
                out[n, s + 1, j] = y


_kernels = compiled.Kernels(globals())


def integrate(g: torch.Tensor, y0: torch.Tensor, f: torch.Tensor, k: float, c: float, dt: float,
              out: torch.Tensor) -> torch.Tensor:
    """Fill ``out`` ``(N, S + 1, J)`` with the trajectory from ``y0`` (at rest) under goals ``g``
    ``(N, J)`` and forcing ``f`` ``(S, N, J)`` (float32, contiguous CPU tensors)."""
    f32 = np.float32
    _kernels("loop")(g.contiguous().numpy(), y0.contiguous().numpy(), f.contiguous().numpy(), f32(k), f32(c), f32(dt),
                 out.numpy())
    return out
