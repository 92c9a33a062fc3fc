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

import contextlib

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



def subnormals_flushed() -> bool:
    """Whether this thread now flushes subnormal floats to zero (probed: ``1e-38 * 0.01``)."""
    return bool(torch.tensor([1e-38]) * 0.01 == 0)


@contextlib.contextmanager
def flush_subnormals(on: bool = True):
    """Run the block with subnormal floats (below ``torch.finfo(dtype).tiny``, 1.2e-38 in float32)
    read and written as zero on this thread (the CPU's flush-to-zero / denormals-are-zero modes),
    restoring the previous mode afterwards; yields whether the CPU has the mode.

    Population codes hold Gaussian tails far below that size, and on x86 an arithmetic operation
    with a subnormal operand or result takes a slow microcode path: a product over such codes can
    run thirty times slower. Flushing changes only values that are themselves subnormal; a sum
    whose terms reach the normal range keeps its bits unless one of its partial sums stays within
    a factor ``2^24`` of the subnormal range. Torch's intra-op worker threads keep their own mode,
    so on several threads some of those subnormal values are kept."""
    before = subnormals_flushed()
    supported = torch.set_flush_denormal(bool(on))
    try:
        yield supported
    finally:
        if supported:
            torch.set_flush_denormal(before)
