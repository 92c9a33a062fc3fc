"""The fixed layout of the Experiment 6 network (:mod:`neuroimagery.models.rotation_3d`): the camera
axes and PMCm's move units, the forward models' receptive radius and the grid their memory budget
allows, the completion map's receptive field, and the correspondence
that matched principal axes and one sign combination give. No learning here."""
from __future__ import annotations

import itertools
import math

import torch

from ..nn.local import offset_count

AXES = ("x", "y", "z")
WRIST_AXIS = "z"  # the line of sight: the axis the wrist turns the held object about (as in Exp 4)
MOVES = ("still",) + tuple(f"{a}{s}" for a in AXES for s in ("-", "+"))  # PMCm units
SIGNS = [torch.tensor(s, dtype=torch.float64) for s in itertools.product((1.0, -1.0), repeat=3)]  # axis sign combinations


def move_angles(step: float) -> list[tuple[str | None, float]]:
    """(axis, degrees) of every PMCm unit, in :data:`MOVES` order."""
    return [(None, 0.0)] + [(a, s * step) for a in AXES for s in (-1.0, 1.0)]


def receptive_radius(side: int, step_deg: float) -> int:
    """Radius covering the largest displacement of one step inside the dot ball of radius G/2 - 1.5."""
    r = side / 2.0 - 1.5
    return int(math.ceil(2.0 * r * math.sin(math.radians(step_deg) / 2.0) - 1e-9))


def fm_bytes(side: int, step_deg: float, moves: int = len(MOVES) - 1) -> int:
    """Bytes of the forward models of one participant (float32)."""
    return moves * side ** 3 * offset_count(receptive_radius(side, step_deg)) * 4


def grid_for_budget(budget_mb: float, step_deg: float, moves: int = len(MOVES) - 1) -> int:
    """The largest even grid side in [8, 64] whose forward models fit ``budget_mb`` per participant."""
    best = None
    for g in range(8, 65, 2):
        if fm_bytes(g, step_deg, moves) <= budget_mb * 1e6:
            best = g
    if best is None:
        raise ValueError(f"a forward-model budget of {budget_mb} MB per participant holds no grid of side >= 8")
    return best


def fill_offsets(depth: int, lateral: int = 1) -> torch.Tensor:
    """Receptive field of C_fill ``(K, 3)`` (z, y, x): the voxels in front of a voxel along the line of
    sight (dz = -1 .. depth toward the eye) and their lateral neighbours up to ``lateral`` voxels."""
    r = torch.arange(-lateral, lateral + 1)
    return torch.tensor([(dz, dy, dx) for dz in range(-1, depth + 1) for dy in r.tolist() for dx in r.tolist()])


def matched_axes(Et: torch.Tensor, Ec: torch.Tensor, signs: torch.Tensor) -> torch.Tensor:
    """The rotation (or reflection) ``(rows, 3, 3)`` taking the comparison image's principal axes ``Ec``
    onto the target's ``Et`` (rows of each ``(rows, 3, 3)`` matrix are the axes), each axis of the
    comparison taken with the sign in ``signs`` ``(3,)``: comparison coordinates -> target coordinates."""
    return Et.transpose(1, 2) @ torch.diag(signs) @ Ec
