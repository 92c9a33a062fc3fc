"""How far two evaluations of the same floating-point sum may differ.

A BLAS product or a reduction adds its terms in an order that depends on the kernel (AVX2 or
AVX-512, matrix-vector or matrix-matrix, the blocking chosen for the shapes, the number of
threads). Results are therefore reproducible only for the same kernel on the same shapes; a cache
compared with the direct product, or a checkpoint rebuilt on another CPU, is compared with the
bound below instead of bit for bit.

The standard bound (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., eq. 3.5
and section 4.2): a sum of ``n`` products evaluated in floating point in *any* order, with or
without fused multiply-adds, lies within ``gamma_n * sum |a_i b_i|`` of the exact value, where
``gamma_n = n u / (1 - n u)`` and ``u = eps / 2`` is the unit roundoff. Two evaluations therefore
differ by at most ``2 gamma_n * sum |a_i b_i|``, which is :func:`rounding_bound`. It is a worst
case: typical differences are a few units in the last place.
"""
from __future__ import annotations

import torch


def rounding_bound(magnitude: torch.Tensor | float, n_terms: int, dtype: torch.dtype = torch.float32):
    """Largest difference between two evaluations, in ``dtype`` and in any order, of sums of
    ``n_terms`` terms (products count as one term each) whose absolute values sum to
    ``magnitude``: ``2 gamma_n magnitude`` with ``gamma_n = n u / (1 - n u)``, ``u = eps / 2``."""
    u = torch.finfo(dtype).eps / 2
    nu = n_terms * u
    if nu >= 1:
        raise ValueError(f"rounding_bound: {n_terms} terms are too many for {dtype} (n u >= 1)")
    return 2 * nu / (1 - nu) * magnitude


def rounding_bound_nonneg(computed: torch.Tensor, n_terms: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """:func:`rounding_bound` for sums of ``n_terms`` non-negative terms, from one ``computed``
    value of the sum: their absolute values sum to the exact sum, which is at most
    ``computed / (1 - gamma_n)``."""
    nu = n_terms * torch.finfo(dtype).eps / 2
    return rounding_bound(computed / (1 - nu / (1 - nu)), n_terms, dtype)


def cast_bound(value: torch.Tensor, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """Largest difference that rounding to ``dtype`` adds between two values: one unit in the
    last place of ``value`` (``eps |value|``, at least the smallest normal number)."""
    fi = torch.finfo(dtype)
    return (fi.eps * value.abs()).clamp_min(fi.tiny)
