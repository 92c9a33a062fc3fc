"""3-D voxel maps for Experiment 6: from seen points to a binary map, random 3-D dots, rotations of
maps by a nearest-neighbour 3-D warp, blur and orthogonal projections (the graded code built on
them is :mod:`neuroimagery.models.voxel_code`).

A map is a flat tensor ``(..., G^3)``; voxel ``(z, y, x)`` is index ``(z G + y) G + x``, with the
camera axes x right, y up, z toward the eye. The map centre is ``(G - 1) / 2`` on each axis.
"""
from __future__ import annotations

import math

import numpy as np
import torch


def _rot(axis: str, deg: float) -> np.ndarray:
    t = math.radians(deg)
    c, s = math.cos(t), math.sin(t)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def grid_coords(side: int) -> np.ndarray:
    """(x, y, z) coordinates relative to the map centre of every voxel, ``(G^3, 3)``, in index order."""
    c = (side - 1) / 2.0
    z, y, x = np.meshgrid(np.arange(side), np.arange(side), np.arange(side), indexing="ij")
    return np.stack([x.ravel() - c, y.ravel() - c, z.ravel() - c], axis=1)


def points_to_map(points: np.ndarray, side: int, voxel: float, extend: float = 0.0, steps: int = 0,
                  centre: np.ndarray | None = None) -> torch.Tensor:
    """Binary map ``(G^3,)`` of camera-frame points (metres), centred on their centroid (or on
    ``centre``) and scaled by ``voxel`` metres per voxel. ``extend`` > 0 (metres) also marks
    ``steps`` points behind each point along its line of sight (away from the eye), up to
    ``extend`` further."""
    pts = np.asarray(points, float)
    out = torch.zeros(side ** 3)
    if len(pts) == 0:
        return out
    if extend > 0 and steps > 0:
        ray = pts / np.linalg.norm(pts, axis=1, keepdims=True)  # from the eye (origin) to the point
        pts = np.concatenate([pts + ray * (extend * s / steps) for s in range(steps + 1)])
        centroid = np.asarray(points, float).mean(0)  # centred on what is seen
    else:
        centroid = pts.mean(0)
    if centre is not None:
        centroid = np.asarray(centre, float)
    v = (pts - centroid) / voxel + (side - 1) / 2.0
    idx = np.round(v).astype(int)
    ok = ((idx >= 0) & (idx < side)).all(1)
    idx = idx[ok]
    flat = (idx[:, 2] * side + idx[:, 1]) * side + idx[:, 0]
    out[torch.from_numpy(np.unique(flat))] = 1.0
    return out


def dot_ball(side: int) -> np.ndarray:
    """Flat indices of the voxels whose centre lies within ``G/2 - 1.5`` of the map centre."""
    r = side / 2.0 - 1.5
    return np.nonzero((grid_coords(side) ** 2).sum(1) <= r * r)[0]


def warp_index(side: int, axis: str | None, deg: float) -> torch.Tensor:
    """Source voxel of every voxel for a turn of ``deg`` about ``axis`` through the map centre
    (nearest-neighbour inverse mapping, as an affine warp samples); ``G^3`` (zero pad) when the
    source falls outside. ``axis=None``: the identity."""
    n = side ** 3
    if axis is None or deg == 0:
        return torch.arange(n)
    g = grid_coords(side)
    src = g @ _rot(axis, deg)  # R^-1 g = R^T g, as rows: g @ R
    idx = np.round(src + (side - 1) / 2.0).astype(int)
    ok = ((idx >= 0) & (idx < side)).all(1)
    flat = (idx[:, 2] * side + idx[:, 1]) * side + idx[:, 0]
    return torch.from_numpy(np.where(ok, flat, n))


def warp(maps: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """Apply a :func:`warp_index` to maps ``(..., G^3)``."""
    pad = torch.cat([maps, maps.new_zeros(*maps.shape[:-1], 1)], -1)
    return pad[..., index]


def projections(m: torch.Tensor, side: int) -> dict:
    """Three orthogonal maximum projections of one map ``(G^3,)``: ``front`` (along the line of sight,
    x right, y up), ``top`` (along the vertical, x right, z toward the eye down) and ``side`` (along
    x, z toward the eye right, y up), each ``(G, G)`` with row 0 at the top."""
    v = m.reshape(side, side, side)  # (z, y, x)
    front = v.amax(0).flip(0)  # (y, x), y up
    top = v.amax(1)  # (z, x): rows = z from far (0) to near
    side_v = v.amax(2).T.flip(0)  # (y, z), y up
    return {"front": front, "top": top, "side": side_v}


def overlap_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Intersection over union of binary maps along the last axis (1 when both empty)."""
    a, b = a > 0.5, b > 0.5
    inter = (a & b).sum(-1).double()
    union = (a | b).sum(-1).double()
    return torch.where(union > 0, inter / union.clamp(min=1), torch.ones_like(union)).float()


def dot_indices(n: int, side: int, generator: torch.Generator, dots: int = 3) -> torch.Tensor:
    """The active voxels ``(n, dots)`` of :func:`dot_images` (same draws: ``dot_images`` scatters these)."""
    ball = torch.from_numpy(dot_ball(side))
    return ball[torch.randint(len(ball), (n, dots), generator=generator)]


def warp_targets(index: torch.Tensor) -> torch.Tensor:
    """For a :func:`warp_index`, the voxels each input voxel becomes: ``(G^3 + 1, M)``, -1 padded
    (row ``G^3``, the pad, reaches nothing). ``warp(x)`` is on exactly at ``targets[active of x]``."""
    n = index.numel()
    ok = index < n
    src, dst = index[ok], torch.arange(n)[ok]
    order = torch.argsort(src, stable=True)
    src, dst = src[order], dst[order]
    counts = torch.bincount(src, minlength=n + 1)
    M = max(1, int(counts.max()))
    out = torch.full((n + 1, M), -1, dtype=torch.long)
    start = torch.cumsum(counts, 0) - counts
    rank = torch.arange(src.numel()) - start[src]
    out[src, rank] = dst
    return out


def blur(maps: torch.Tensor, side: int, sigma: float) -> torch.Tensor:
    """Maps ``(..., G^3)`` smoothed by an isotropic Gaussian of ``sigma`` voxels (zero outside the grid):
    every voxel of a broadly tuned population code responds to the active voxels around it."""
    if sigma <= 0:
        return maps
    shape = maps.shape
    r = int(math.ceil(3 * sigma))
    t = torch.arange(-r, r + 1, dtype=maps.dtype)
    k = torch.exp(-t * t / (2 * sigma * sigma))
    k = k / k.sum()
    v = maps.reshape(-1, 1, side, side, side)
    v = torch.nn.functional.conv3d(v, k.view(1, 1, -1, 1, 1), padding=(r, 0, 0))
    v = torch.nn.functional.conv3d(v, k.view(1, 1, 1, -1, 1), padding=(0, r, 0))
    v = torch.nn.functional.conv3d(v, k.view(1, 1, 1, 1, -1), padding=(0, 0, r))
    return v.reshape(shape)
