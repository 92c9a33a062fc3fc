"""Reflections of a square binary map about a fixed line through its centre
(:func:`reflection_index`). The flipped targets (PFCft) of Experiments 4 and 6 are made this way."""
from __future__ import annotations

import math

import torch


def reflection_index(size: int, axis_deg: float) -> torch.Tensor:
    """Source pixel of every destination pixel for a reflection of a ``size x size`` map about the
    line through its centre at ``axis_deg`` (counter-clockwise from the x axis, as seen on screen).
    Pixels whose source falls outside get index ``size*size`` (a zero pad)."""
    c = (size - 1) / 2.0
    ys, xs = torch.meshgrid(torch.arange(size, dtype=torch.float64), torch.arange(size, dtype=torch.float64), indexing="ij")
    t = math.radians(axis_deg)
    dx, dy = xs - c, -(ys - c)  # y up
    cos2, sin2 = math.cos(2 * t), math.sin(2 * t)
    sx, sy = cos2 * dx + sin2 * dy, sin2 * dx - cos2 * dy
    col, row = torch.round(sx + c).long(), torch.round(c - sy).long()
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    return torch.where(ok, row * size + col, torch.full_like(col, size * size)).reshape(-1)
