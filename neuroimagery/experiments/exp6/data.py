"""What Experiment 6's eye sees and what its stages learn from: the objects, the 3-D surface map of
a view, the whole-volume map of the same view (the completion map's target), random cube chains
in random poses, graded dot images for the forward models, and the bank of views (as the model
sees them) that a set of same / mirror pairs needs."""
from __future__ import annotations

import math

import numpy as np
import torch

from ...core.errors import UserInputError
from ...models import voxel_code as vc
from ...models import voxels
from ...vision import shepard_metzler as sm


def grid_side(e) -> int:
    from ...models.rotation_3d import grid_for_budget

    return int(e.grid) if e.grid is not None else grid_for_budget(e.fm.memory_mb, e.step_deg)


def built_objects(e) -> list[np.ndarray]:
    """The generator's objects in the order drawn: the training objects, then the test set."""
    o = e.objects
    return sm.generate(o.train + o.test, seed=o.seed, min_margin=o.mirror_cubes)


def objects(e) -> tuple[list[np.ndarray], list[str], list[np.ndarray], list[str]]:
    """(training objects, names, test objects, names)."""
    o, built = e.objects, built_objects(e)
    train, test = built[:o.train], built[o.train:]
    tnames = [f"T{i + 1}" for i in range(len(train))]
    if o.test_cubes is not None:
        test = [sm.check_object(c, f"experiment.objects.test_cubes[{i}]", o.mirror_cubes)
                for i, c in enumerate(o.test_cubes)]
        return train, tnames, test, [f"U{i + 1}" for i in range(len(test))]
    if o.test_set == "train":
        return train, tnames, list(train), list(tnames)
    return train, tnames, test, [f"S{i + 1}" for i in range(len(test))]


def reach(e) -> float:
    """The furthest any built-in object reaches from its centroid (cube centre plus half a diagonal), cubes."""
    built = built_objects(e)
    return max(float(np.linalg.norm(sm.centred(c), axis=1).max()) for c in built) + math.sqrt(3) / 2


def cube_voxels(e, side: int) -> float:
    """Voxels per cube edge: ``e.cube_voxels``, or the largest scale at which every built-in object
    fits the dot ball (radius G/2 - 1.5) in every orientation."""
    if e.cube_voxels is not None:
        return float(e.cube_voxels)
    return (side / 2.0 - 1.5) / reach(e)


def make_scene(e) -> sm.SMScene:
    v = e.view
    return sm.SMScene(eye=v.eye, width=v.image_width, height=v.image_height, fov_deg=v.fov_deg,
                      distance=v.object_distance, cube_edge=v.cube_edge)


def _volume_points(centres: np.ndarray, rot: np.ndarray, e) -> np.ndarray:
    """Camera-frame points (metres) filling every cube of an object turned by ``rot``."""
    t = (np.arange(4) - 1.5) / 4.0
    sub = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    pts = (np.asarray(centres)[:, None, :] + sub[None]).reshape(-1, 3)
    return (pts @ np.asarray(rot).T) * e.view.cube_edge + np.array([0.0, 0.0, -e.view.object_distance])


def view(scene, e, side: int, scale: float, centres: np.ndarray, rot: np.ndarray, whole: bool = False):
    """The surface map ``(G^3,)`` of centred cube centres ``centres`` turned by ``rot`` as the eye sees
    them, centred on what is seen; with ``whole`` also the map of the whole volume in the same frame."""
    pts = sm.red_points(scene.look(centres, rot), e.view.red_threshold)
    if len(pts) == 0:
        raise UserInputError("exp6: the eye sees no red pixels of an object (is it in the field of view?)")
    vox = e.view.cube_edge / scale
    surf = voxels.points_to_map(pts, side, vox)
    if not whole:
        return surf
    return surf, voxels.points_to_map(_volume_points(centres, rot, e), side, vox, centre=pts.mean(0))


def see(scene, e, side: int, scale: float, cells: np.ndarray, appearance: str, kind, angle: float) -> torch.Tensor:
    """The surface map of one test view: ``angle`` deg of rotation ``kind`` from the general view."""
    c = sm.centred(cells) if appearance == "basic" else sm.mirror(cells)
    return view(scene, e, side, scale, c, sm.pose(kind, angle, e.view.tilt_deg, e.view.turn_deg))


def chains(e, count: int, seed: int, stream: int) -> list[np.ndarray]:
    """Random cube chains (never a built-in object) that fit the map as the built-in objects do."""
    rng = np.random.default_rng([seed, stream, 6])
    return sm.random_chains(count, rng, exclude=built_objects(e), max_radius=reach(e),
                            min_margin=e.objects.mirror_cubes)


def chain_views(scene, e, side: int, scale: float, count: int, seed: int, stream: int, mirror: bool = False):
    """``count`` random chains each in a random pose: (surface maps, whole maps) ``(count, G^3)``, the
    chains and the poses. ``mirror``: the chains' mirror objects instead, in the same poses."""
    cs = chains(e, count, seed, stream)
    rots = vc.random_rotations(count, torch.Generator().manual_seed(int(seed) * 1000 + int(stream))).numpy()
    surf, whole = [], []
    for c, r in zip(cs, rots):
        s, w = view(scene, e, side, scale, sm.mirror(c) if mirror else sm.centred(c), r, whole=True)
        surf.append(s)
        whole.append(w)
    return torch.stack(surf), torch.stack(whole), cs, rots


def dot_positions(n: int, dots: int, side: int, generator: torch.Generator) -> torch.Tensor:
    """``(n, dots, 3)`` positions uniform in the dot ball (radius G/2 - 1.5 about the map centre)."""
    r = side / 2.0 - 1.5
    v = torch.randn(n, dots, 3, generator=generator, dtype=torch.float64)
    v = v / v.norm(dim=-1, keepdim=True)
    rad = r * torch.rand(n, dots, 1, generator=generator, dtype=torch.float64) ** (1.0 / 3.0)
    return v * rad


def dot_pair(gens, n: int, dots: int, side: int, sigma: float, R: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Graded dot images ``(P, n, G^3)`` (one draw per participant generator) and the same dots turned by ``R``."""
    pos = torch.stack([dot_positions(n, dots, side, g) for g in gens])  # (P, n, D, 3)
    P = pos.shape[0]
    flat = pos.reshape(P * n, dots, 3)
    x = vc.blobs(flat.float(), side, sigma)
    y = vc.blobs((flat @ R.T).float(), side, sigma)
    return x.reshape(P, n, -1), y.reshape(P, n, -1)


def pair_bank(model, cfg, scene, cells_list, names, kinds, ids, angles_of) -> tuple[torch.Tensor, dict]:
    """Images ``(P, N, n)`` (coded, completed, centred by each participant) of every view the pairs of
    ``cells_list`` need, and ``{(object, kind, angle, appearance): row}``."""
    e = cfg.experiment
    occ, index = [], {}
    for cells, name in zip(cells_list, names):
        for app in ("basic", "mirror"):
            for kind in kinds:
                for ang in angles_of(kind):
                    key = (name, kind, float(ang), app)
                    zero = (name, None, 0.0, app)
                    if ang == 0 and zero in index:
                        index[key] = index[zero]
                        continue
                    index[key] = len(occ)
                    if ang == 0:
                        index[zero] = len(occ)
                    occ.append(see(scene, e, model.side, model.cube_voxels, cells, app, kind, ang))
            if (name, None, 0.0, "basic") not in index:
                index[(name, None, 0.0, "basic")] = len(occ)
                occ.append(see(scene, e, model.side, model.cube_voxels, cells, "basic", None, 0.0))
    occ = torch.stack(occ)
    P = len(ids)
    part = torch.arange(P).repeat_interleave(len(occ))
    images = model.image(occ.repeat(P, 1), part).reshape(P, len(occ), -1)
    return images, index
