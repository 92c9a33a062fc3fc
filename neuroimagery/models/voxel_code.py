"""The graded 3-D population code of Experiment 6's images.

Every voxel of a ``G x G x G`` map is a unit broadly tuned to 3-D position: it responds to the
occupied voxels around it with a Gaussian of ``sigma`` voxels, its activity cut at 1
(:func:`graded`). Dots at sub-voxel positions give Gaussian bumps (:func:`blobs`). Maps are
flat ``(..., G^3)`` with voxel ``(z, y, x)`` at ``(z G + y) G + x`` and the camera axes x right,
y up, z toward the eye, as :mod:`neuroimagery.models.voxels`.

Fixed operations on maps (no learning): the exact rotation by trilinear resampling
(:func:`rotate`, used only to make training targets and to measure), centring on the centre of
activity (:func:`recentre`, the 3-D counterpart of centring an edge map on the object), the
cosine of two maps and the size of the largest connected cluster of a binary map
(:func:`largest_cluster`, by spreading labels to the 26 neighbours).
"""
from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F

from . import voxel_code_kernel, voxels


SILENT = 0.01  # a unit driven below this fraction of its peak stays silent (keeps the codes sparse)


def _grid(maps: torch.Tensor, side: int) -> torch.Tensor:
    return maps.reshape(-1, 1, side, side, side)


def graded(occ: torch.Tensor, side: int, sigma: float) -> torch.Tensor:
    """The population code of binary maps ``occ`` ``(..., G^3)``: each unit's Gaussian tuning
    (``sigma`` voxels) over the occupied voxels, scaled so that one isolated voxel drives its own
    unit to 1, cut at 1."""
    if sigma <= 0:
        return occ.clone()
    peak = _peak(sigma)
    out = (voxels.blur(occ, side, sigma) / peak).clamp(0.0, 1.0)
    return torch.where(out >= SILENT, out, torch.zeros_like(out))


def _peak(sigma: float) -> float:
    r = int(math.ceil(3 * sigma))
    t = np.arange(-r, r + 1)
    k = np.exp(-t * t / (2 * sigma * sigma))
    return float((k.max() / k.sum()) ** 3)


def blobs(points: torch.Tensor, side: int, sigma: float) -> torch.Tensor:
    """Maps ``(N, G^3)`` of Gaussian dots (peak 1, ``sigma`` voxels) at sub-voxel positions
    ``points`` ``(N, D, 3)`` (x, y, z relative to the map centre); overlapping dots add, cut at 1,
    units below :data:`SILENT` silent."""
    N, D, _ = points.shape
    r = int(math.ceil(math.sqrt(-2.0 * math.log(SILENT)) * sigma))
    t = torch.arange(-r, r + 1)
    off = torch.stack(torch.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)  # (W, 3) as (x, y, z)
    c = (side - 1) / 2.0
    pos = points.double() + c  # voxel coordinates
    near = torch.round(pos).long()  # (N, D, 3)
    if voxel_code_kernel.available() and points.device.type == "cpu":  # the same numbers, compiled
        arg, flat = voxel_code_kernel.arguments(pos, near, t, side, 2 * sigma * sigma)
        return voxel_code_kernel.scatter(torch.exp(arg).float(), flat, side ** 3, SILENT)
    vox = near.unsqueeze(2) + off.view(1, 1, -1, 3)  # (N, D, W, 3)
    d2 = ((vox.double() - pos.unsqueeze(2)) ** 2).sum(-1)
    val = torch.exp(-d2 / (2 * sigma * sigma)).float()
    ok = ((vox >= 0) & (vox < side)).all(-1)
    flat = (vox[..., 2] * side + vox[..., 1]) * side + vox[..., 0]
    flat = torch.where(ok, flat, torch.full_like(flat, side ** 3))
    out = torch.zeros(N, side ** 3 + 1)
    out.scatter_add_(1, flat.reshape(N, -1), torch.where(ok, val, torch.zeros_like(val)).reshape(N, -1))
    out = out[:, :-1].clamp(0.0, 1.0)
    return torch.where(out >= SILENT, out, torch.zeros_like(out))


def _sample(maps: torch.Tensor, side: int, src: torch.Tensor) -> torch.Tensor:
    """Trilinear samples of maps ``(N, G^3)`` at source coordinates ``src`` ``(N, G^3, 3)``
    (x, y, z relative to the centre); zero outside."""
    c = (side - 1) / 2.0
    grid = (src / c).reshape(-1, side, side, side, 3).to(maps.dtype)
    out = F.grid_sample(_grid(maps, side), grid, mode="bilinear", padding_mode="zeros", align_corners=True)
    return out.reshape(maps.shape[0], side ** 3)


def rotate(maps: torch.Tensor, side: int, R: torch.Tensor) -> torch.Tensor:
    """Maps ``(N, G^3)`` turned by rotation matrices ``R`` ``(3, 3)`` or ``(N, 3, 3)`` about the map
    centre (the activity at ``g`` moves to ``R g``), trilinear."""
    N = maps.shape[0]
    g = torch.from_numpy(voxels.grid_coords(side)).to(maps.dtype)
    R = torch.as_tensor(R, dtype=maps.dtype)
    R = R.expand(N, 3, 3) if R.dim() == 2 else R
    src = torch.einsum("nj,bjk->bnk", g, R)  # R^T g as rows: g R
    return _sample(maps, side, src)


def centre_of(maps: torch.Tensor, side: int) -> torch.Tensor:
    """Centre of activity ``(N, 3)`` (x, y, z relative to the map centre)."""
    g = torch.from_numpy(voxels.grid_coords(side)).to(maps.dtype)
    m = maps.sum(-1, keepdim=True).clamp_min(1e-12)
    return (maps @ g) / m


def recentre(maps: torch.Tensor, side: int) -> torch.Tensor:
    """Maps ``(N, G^3)`` shifted (trilinear) so that their centre of activity is the map centre."""
    g = torch.from_numpy(voxels.grid_coords(side)).to(maps.dtype)
    m = centre_of(maps, side)
    return _sample(maps, side, g.unsqueeze(0) + m.unsqueeze(1))


def second_moment(maps: torch.Tensor, side: int) -> torch.Tensor:
    """Activity-weighted second moments ``(N, 3, 3)`` of the voxel positions about the centre of activity."""
    g = torch.from_numpy(voxels.grid_coords(side)).to(maps.dtype)
    m = maps.sum(-1).clamp_min(1e-12)
    d = g.unsqueeze(0) - centre_of(maps, side).unsqueeze(1)
    return torch.einsum("bn,bni,bnj->bij", maps, d, d) / m.view(-1, 1, 1)


def cosine(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Cosine of maps along the last axis (0 when either is empty)."""
    num = (a * b).sum(-1)
    den = a.norm(dim=-1) * b.norm(dim=-1)
    return torch.where(den > 0, num / den.clamp_min(1e-12), torch.zeros_like(num))


def largest_cluster(mask: torch.Tensor, side: int) -> torch.Tensor:
    """Voxels ``(N,)`` in the largest 26-connected cluster of each binary map ``(N, G^3)``: every
    active voxel takes the largest label among its active neighbours until nothing changes."""
    N, n = mask.shape
    on = mask > 0.5
    if not on.any():
        return torch.zeros(N, dtype=torch.long)
    if voxel_code_kernel.available() and on.device.type == "cpu":  # the same clusters, compiled
        return voxel_code_kernel.largest_cluster(on, side)
    lab = torch.where(on, torch.arange(1, n + 1, dtype=torch.float32).expand(N, n), torch.zeros(N, n))
    for _ in range(n):
        new = F.max_pool3d(_grid(lab, side), 3, stride=1, padding=1).reshape(N, n)
        new = torch.where(on, new, torch.zeros_like(new))
        if torch.equal(new, lab):
            break
        lab = new
    lab = lab.long()
    counts = torch.zeros(N, n + 1, dtype=torch.long)
    counts.scatter_add_(1, lab, torch.ones_like(lab))
    counts[:, 0] = 0
    return counts.max(-1).values


def random_rotations(n: int, generator: torch.Generator) -> torch.Tensor:
    """``n`` rotation matrices ``(n, 3, 3)`` uniform over the rotations (QR of Gaussian matrices)."""
    a = torch.randn(n, 3, 3, generator=generator, dtype=torch.float64)
    q, r = torch.linalg.qr(a)
    q = q * torch.sign(torch.diagonal(r, dim1=-2, dim2=-1)).unsqueeze(-2)
    det = torch.linalg.det(q)
    q[:, :, 0] *= det.unsqueeze(-1)
    return q


def axis_angle(R: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Unit axes ``(N, 3)`` and angles ``(N,)`` (degrees, 0-180) of rotation matrices ``(N, 3, 3)``."""
    R = R.double()
    tr = torch.diagonal(R, dim1=-2, dim2=-1).sum(-1)
    ang = torch.arccos(((tr - 1) / 2).clamp(-1, 1))
    v = torch.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    axis = v / v.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    near = ang > math.pi - 1e-3  # about 180 deg the skew part vanishes: the axis from R + I
    if near.any():
        B = (R[near] + torch.eye(3, dtype=R.dtype)) / 2
        col = B.diagonal(dim1=-2, dim2=-1).argmax(-1)
        a = B[torch.arange(B.shape[0]), :, col]
        axis[near] = a / a.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    return axis, torch.rad2deg(ang)


def rotation_vector(R: torch.Tensor) -> torch.Tensor:
    """Rotation vectors ``(N, 3)`` (axis times angle in degrees) of rotation matrices."""
    axis, ang = axis_angle(R)
    return axis * ang.unsqueeze(-1)


def axis_rotation(axis: str, deg: float) -> torch.Tensor:
    """The rotation matrix of ``deg`` about camera axis ``x``, ``y`` or ``z``."""
    return torch.from_numpy(voxels._rot(axis, deg)).double()
