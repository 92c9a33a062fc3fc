"""Population-coded neural maps (thesis section 4.2, eq. 4.1).

A map is a named 1-D or 2-D grid of units. Each unit has a preferred value (its coordinate in
the encoded space); a scalar or 2-D value is represented as a Gaussian bump of activity centred
on the units that prefer it, and read back by centre of mass (or by the most active unit).
"""
from __future__ import annotations

from typing import Sequence

import torch
from torch import nn

from .functional import check_rate, check_tensor, gaussian_bump


class PopulationMap(nn.Module):
    """A grid of ``shape`` units whose activity lives in the buffer ``activity`` ``(P, B, *shape)``.

    Args:
        name: label used in logs and TensorBoard.
        shape: ``(n,)`` or ``(rows, cols)``.
        low, high: the encoded range along each grid axis (scalars or one per axis). Unit ``k`` of an
            axis with ``n`` units prefers ``low + k (high - low) / (n - 1)``.
        sigma: width of the Gaussian tuning curve in encoded units (eq. 4.1).
        noise: standard deviation of the additive noise ``n_i`` of eq. 4.1 (0 = noise free).
    """

    def __init__(self, name: str, shape: Sequence[int], low: float | Sequence[float] = 0.0,
                 high: float | Sequence[float] = 1.0, sigma: float = 0.1, noise: float = 0.0) -> None:
        super().__init__()
        shape = tuple(int(s) for s in shape)
        if len(shape) not in (1, 2) or min(shape) < 1:
            raise ValueError(f"map {name!r}: shape must be (n,) or (rows, cols) of positive sizes, got {shape}")
        self.name = name
        self.shape = shape
        self.sigma = check_rate("sigma", sigma, open_low=True)
        self.noise = check_rate("noise", noise)
        d = len(shape)
        lows = [float(low)] * d if not isinstance(low, (list, tuple)) else [float(v) for v in low]
        highs = [float(high)] * d if not isinstance(high, (list, tuple)) else [float(v) for v in high]
        if len(lows) != d or len(highs) != d:
            raise ValueError(f"map {name!r}: low/high need {d} values")
        axes = [torch.linspace(lo, hi, n) if n > 1 else torch.tensor([lo]) for lo, hi, n in zip(lows, highs, shape)]
        grid = torch.meshgrid(*axes, indexing="ij")
        self.register_buffer("coords", torch.stack([g.reshape(-1) for g in grid], dim=-1))  # (n, D)
        self.register_buffer("activity", torch.zeros(1, 1, *shape))

    @property
    def n(self) -> int:
        """Number of units."""
        return self.coords.shape[0]

    def encode(self, values: torch.Tensor, amplitude: float = 1.0, generator: torch.Generator | None = None) -> torch.Tensor:
        """Gaussian population code of ``values``.

        ``values``: ``(...)`` for a 1-D map or ``(..., 2)`` for a 2-D map. Returns ``(..., *shape)``.
        With ``noise > 0`` the noise term of eq. 4.1 is added (drawn from ``generator``, on its
        device). The code has the map's dtype and device (those of ``coords``).
        """
        values = torch.as_tensor(values, dtype=self.coords.dtype, device=self.coords.device)
        if len(self.shape) == 1:
            values = values.unsqueeze(-1)
        else:
            check_tensor("values", values, (2,))
        out = gaussian_bump(values, self.coords, self.sigma, amplitude)
        if self.noise > 0:
            g_dev = out.device if generator is None else generator.device
            z = torch.randn(out.shape, generator=generator, dtype=out.dtype, device=g_dev)
            out = out + self.noise * z.to(out.device)
        return out.reshape(*out.shape[:-1], *self.shape)

    def decode(self, activity: torch.Tensor, method: str = "com") -> torch.Tensor:
        """Read a value back from ``activity`` ``(..., *shape)``.

        ``com``: centre of mass of the (rectified) activity; ``argmax``: preferred value of the most
        active unit. Returns ``(...)`` for 1-D maps, ``(..., 2)`` for 2-D maps. All-zero activity
        decodes to NaN under ``com``.
        """
        check_tensor("activity", activity, self.shape, finite=False)
        flat = activity.reshape(*activity.shape[: activity.dim() - len(self.shape)], self.n)
        if method == "argmax":
            val = self.coords[flat.argmax(-1)]
        elif method == "com":
            w = flat.clamp_min(0)
            val = (w.unsqueeze(-1) * self.coords).sum(-2) / w.sum(-1, keepdim=True)
        else:
            raise ValueError(f"decode method must be 'com' or 'argmax', got {method!r}")
        return val.squeeze(-1) if len(self.shape) == 1 else val

    def set(self, activity: torch.Tensor) -> torch.Tensor:
        """Store ``activity`` (``(P, B, *shape)``) as the map's current state and return it."""
        check_tensor("activity", activity, self.shape)
        self.activity = activity.detach()
        return activity

    def flat(self, activity: torch.Tensor | None = None) -> torch.Tensor:
        """``activity`` (default: the stored one) with the grid axes flattened to ``n``."""
        a = self.activity if activity is None else activity
        return a.reshape(*a.shape[: a.dim() - len(self.shape)], self.n)

    def unflat(self, flat: torch.Tensor) -> torch.Tensor:
        """Inverse of :meth:`flat`."""
        return flat.reshape(*flat.shape[:-1], *self.shape)

    def reset_state(self) -> None:
        """Silence the map."""
        self.activity = self.coords.new_zeros(1, 1, *self.shape)

    def extra_repr(self) -> str:
        return f"name={self.name!r}, shape={self.shape}, sigma={self.sigma}"


def population_cover(x: torch.Tensor, size: int, reach: int = 1) -> torch.Tensor:
    """What a square image map ``x`` ``(..., size*size)`` covers when read as a population code whose
    units respond over their ``(2 reach + 1)^2`` neighbourhood (Chebyshev distance ``reach``): the
    maximum of the map over each unit's neighbourhood, same shape as ``x``. ``reach=0`` is the map
    itself (one-to-one). A bool map gives a bool map: whether any unit of the neighbourhood is on
    (the maximum of its 0/1 values), computed by shifted ORs along each axis."""
    r = int(reach)
    if r < 0:
        raise ValueError(f"reach must be >= 0, got {reach}")
    if r == 0:
        return x
    shape = x.shape
    if x.dtype == torch.bool:
        return _dilate(x.reshape(-1, size, size), r).reshape(shape)
    flat = x.reshape(-1, 1, size, size).float()
    return torch.nn.functional.max_pool2d(flat, 2 * r + 1, 1, r).reshape(shape).to(x.dtype)


def _dilate(b: torch.Tensor, r: int) -> torch.Tensor:
    """Bool maps ``(M, H, W)``: each unit OR-ed with those within Chebyshev distance ``r`` (the
    square neighbourhood, cut at the border), one axis after the other."""
    for axis in (2, 1):
        out = b.clone()
        n = b.shape[axis]
        for d in range(1, min(r, n - 1) + 1):
            out.narrow(axis, d, n - d).logical_or_(b.narrow(axis, 0, n - d))
            out.narrow(axis, 0, n - d).logical_or_(b.narrow(axis, d, n - d))
        b = out
    return b
