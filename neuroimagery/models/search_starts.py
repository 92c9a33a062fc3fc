"""The option ``search.starts`` of Experiment 6's search (docs/exp6.md, docs/choices.md): more starting
points for the local refinement of :meth:`~neuroimagery.models.rotation_3d.Rotation3D.search`.

Each sign combination of the matched principal axes (proper ones only when ``proper``) and its turns
by each angle of ``search.starts`` about each camera axis either way are starting points; every
start is refined at the first scale of ``search.refine`` by the search's coarse comparison, the
``search.keep`` best of each row at the remaining scales, and the best wins.
"""
from __future__ import annotations

import math

import torch

from . import voxel_code as vc
from .layout_3d import AXES, SIGNS, matched_axes


def multi_start(model, Et: torch.Tensor, Ec: torch.Tensor, ct, cc, proper: bool):
    """Rotations ``(rows, 3, 3)`` turning the comparison image onto the target, and whether each is
    proper. ``model``: the :class:`~neuroimagery.models.rotation_3d.Rotation3D` (its ``refine``,
    ``coarse_match`` and ``p.search``); ``Et``, ``Ec``: the two images' principal axes
    ``(rows, 3, 3)``; ``ct``, ``cc``: their coarse codes."""
    p = model.p.search
    turns = [torch.eye(3, dtype=torch.float64)] + [vc.axis_rotation(a, sg * d) for d in p.starts
                                                     for a in AXES for sg in (-1.0, 1.0)]
    scales = list(p.refine)
    n = Et.shape[0]
    Rs, scores = [], []
    for s in SIGNS:
        R0 = matched_axes(Et, Ec, s)
        k = (torch.linalg.det(R0) > 0).nonzero().squeeze(-1) if proper else torch.arange(n)
        sub = tuple(tuple(x[k] for x in code) for code in (ct, cc))
        for U in turns:
            R = U @ R0
            sc = torch.full((n,), -math.inf, dtype=torch.float64)
            if k.numel():
                R = R.clone()
                R[k], sc[k] = model.refine(*sub, R[k], model.coarse_match(*sub, R[k]), scales[:1])
            Rs.append(R)
            scores.append(sc)
    Rs, scores = torch.stack(Rs, 1), torch.stack(scores, -1)  # (rows, starts, 3, 3), (rows, starts)
    rows = torch.arange(n)
    best_R, best_s = None, None
    for j in scores.topk(min(p.keep, scores.shape[1]), -1).indices.T:
        R, sc = Rs[rows, j], scores[rows, j]
        if len(scales) > 1:
            R, sc = model.refine(ct, cc, R, sc, scales[1:])
        if best_R is None:
            best_R, best_s = R, sc
        else:
            up = sc > best_s
            best_R, best_s = torch.where(up.view(-1, 1, 1), R, best_R), torch.where(up, sc, best_s)
    return best_R, torch.linalg.det(best_R) > 0
