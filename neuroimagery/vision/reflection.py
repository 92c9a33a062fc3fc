"""Reflections of a square binary map about a line through it: a fixed axis
(:func:`reflection_index`) or the map's own principal axis (:func:`principal_axis_flip`). The
flipped targets (PFCft) of Experiments 4 and 6 are made this way."""
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


def principal_axis_flip(maps: torch.Tensor, size: int) -> torch.Tensor:
    """C10 as a fixed transformation of the image: each binary map ``(..., size*size)`` reflected about
    its own principal axis, the line through the centroid of its active units along the eigenvector
    of the largest eigenvalue of their second-moment matrix. Pixels whose source falls outside the
    map stay 0; an empty map stays empty."""
    shape = maps.shape
    x = maps.reshape(-1, size * size).to(torch.float64)
    c = (size - 1) / 2.0
    ys, xs = torch.meshgrid(torch.arange(size, dtype=torch.float64), torch.arange(size, dtype=torch.float64), indexing="ij")
    px, py = (xs - c).reshape(-1), (c - ys).reshape(-1)  # y up, as seen on screen
    m = x.sum(-1).clamp_min(1.0)
    cx, cy = (x * px).sum(-1) / m, (x * py).sum(-1) / m
    dx, dy = px - cx.unsqueeze(-1), py - cy.unsqueeze(-1)
    sxx, syy, sxy = (x * dx * dx).sum(-1), (x * dy * dy).sum(-1), (x * dx * dy).sum(-1)
    t2 = torch.atan2(2.0 * sxy, sxx - syy).unsqueeze(-1)  # twice the axis angle
    cos2, sin2 = torch.cos(t2), torch.sin(t2)
    sx, sy = cx.unsqueeze(-1) + cos2 * dx + sin2 * dy, cy.unsqueeze(-1) + sin2 * dx - cos2 * dy  # source of each pixel
    col, row = torch.round(sx + c).long(), torch.round(c - sy).long()
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    idx = torch.where(ok, row * size + col, torch.full_like(col, size * size))
    pad = torch.cat([x, torch.zeros(x.shape[0], 1, dtype=x.dtype)], dim=-1)
    return torch.gather(pad, -1, idx).to(maps.dtype).reshape(shape)
