"""Checks of Experiment 6 that run before any work (``neuroimagery.validation.check_run``): the
memory its settings need (:func:`memory_estimate`) and whether the eye can see the objects and
the map can hold them (:func:`check_inputs`).

The estimate (float32): the forward models (6 local connections on the ``G^3`` voxel map per
participant, ``rotation_3d.fm_bytes``), the chain views the completion map learns from (surface
and whole-volume codes, once, and in each participant's order) and the bank of test images (every
test view of every test object, ``G^3`` each, per participant). It leaves out smaller arrays, so
it is a lower bound of the peak.

Placement rules (fixed before they were checked, from the scene's geometry): the object, a ball of
radius ``rho`` cube edges around its centre, must lie between the eye camera's clipping planes
(0.05 m and 3 m) and inside its field of view, and one cube must cover at least one pixel; a
probe view (the first training object in the general view, one render) must show pixels redder
than ``view.red_threshold``. A set ``cube_voxels`` may not exceed the scale rule's (the largest at
which every object fits the dot ball in every orientation): above it, rotations carry parts of
the object out of the map and no comparison is decided.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.errors import UserInputError
from ...core.resources import Need, culprit
from ...validation import settings_named

FLOAT = 4
NEAR, FAR = 0.05, 3.0  # the eye camera's clipping planes (vision.shepard_metzler.SMScene)


def _grid(e) -> int | None:
    from .data import grid_side

    try:
        return grid_side(e)
    except ValueError:
        return None


def _test_objects(cfg) -> tuple[str, int]:
    e, o = cfg.experiment, cfg.experiment.objects
    if o.test_cubes is not None:
        return "experiment.objects.test_cubes", len(o.test_cubes)
    if o.test_set == "train":
        return "experiment.objects.train", int(o.train)
    if cfg.preset == "quick":
        return "experiment.quick.objects", int(e.quick.objects)
    return "experiment.objects.test", int(o.test)


def memory_estimate(cfg) -> list[Need]:
    """The bytes of the forward models, the chain views and the test images."""
    from ...models.rotation_3d import fm_bytes

    e, P = cfg.experiment, int(cfg.participants)
    G = _grid(e)
    if G is None:  # fm.memory_mb holds no grid: check_inputs names it
        return []
    vox = float(G) ** 3
    gkey = {"experiment.grid" if e.grid is not None else "experiment.fm.memory_mb":
            (G, 18) if e.grid is not None else (float(e.fm.memory_mb), 20.0)}
    n_chain = int(e.quick.chains if cfg.preset == "quick" else e.image.chains)
    ckey = "experiment.quick.chains" if cfg.preset == "quick" else "experiment.image.chains"
    tkey, n_test = _test_objects(cfg)
    views = 2 * len(e.tests) * max(len(e.test_angles), len(e.oblique_angles))
    who = {**gkey, "participants": (P, 10)}
    return [
        Need(culprit(who), float(fm_bytes(G, e.step_deg)) * P, f"forward models, {P} x 6 on a {G}^3 map"),
        Need(culprit({**who, ckey: (n_chain, 1200)}), 4.0 * (P + 2) * n_chain * vox * FLOAT,
             f"chain views for the completion map, {n_chain} x {G}^3, in {P} orders"),
        Need(culprit({**who, tkey: (n_test, 5)}), float(P) * n_test * views * vox * FLOAT,
             f"test images, {P} x {n_test} objects x {views} views x {G}^3"),
    ]


def _objects(e):
    from ...vision import shepard_metzler as sm

    o = e.objects
    n = int(o.train) + int(o.test)
    try:
        return sm.generate(n, seed=o.seed, min_margin=o.mirror_cubes)
    except ValueError:
        raise UserInputError(f"experiment.objects.train + experiment.objects.test = {n}: the object generator "
                             f"finds fewer distinct objects with objects.seed={o.seed} and "
                             f"objects.mirror_cubes={o.mirror_cubes}; ask for fewer "
                             "(or give experiment.objects.test_cubes)") from None


def check_inputs(cfg) -> None:
    """Object count, grid, placement in the eye's view, map scale and a probe view, before training."""
    from ...models.rotation_3d import fm_bytes
    from ...vision import shepard_metzler as sm

    e, v = cfg.experiment, cfg.experiment.view
    G = _grid(e)
    if G is None:
        raise UserInputError(f"experiment.fm.memory_mb={e.fm.memory_mb:g} holds no voxel grid: the smallest "
                             f"(8^3) needs {fm_bytes(8, e.step_deg) / 1e6:.2f} MB per participant")
    built = _objects(e)
    shown = list(built) + [np.asarray(c, float) for c in (e.objects.test_cubes or [])]
    rho = max(float(np.linalg.norm(sm.centred(c), axis=1).max()) for c in shown) + math.sqrt(3) / 2
    radius = rho * v.cube_edge  # metres
    d = float(v.object_distance)
    depth = ("experiment.view.object_distance", "experiment.view.cube_edge")
    view = ("experiment.view.fov_deg", "experiment.view.image_width", "experiment.view.image_height") + depth
    if not NEAR < d - radius or not d + radius < FAR:
        raise UserInputError(f"{settings_named(cfg, depth)}: the object (radius {radius:.3f} m) lies outside "
                             f"the eye's depth range ({NEAR} to {FAR} m): place it within "
                             f"[{NEAR + radius:.2f}, {FAR - radius:.2f}] m")
    half_h = math.radians(v.fov_deg) / 2
    half_w = math.atan(math.tan(half_h) * v.image_width / v.image_height)
    seen = math.atan(radius / d)
    if seen > min(half_h, half_w):
        raise UserInputError(f"{settings_named(cfg, view)}: the object (radius {radius:.3f} m) does not fit the "
                             "eye's field of view; widen the view, move the object farther or make it smaller")
    focal = 0.5 * v.image_height / math.tan(half_h)
    if v.cube_edge * focal / d < 1.0:
        raise UserInputError(f"{settings_named(cfg, view[:1] + view[2:])}: one cube covers "
                             f"{v.cube_edge * focal / d:.2f} pixel of the eye's image; at least 1 is needed "
                             "(a narrower view, a larger image, a nearer or larger object)")
    if e.cube_voxels is not None:
        most = (G / 2.0 - 1.5) / rho
        if float(e.cube_voxels) > most:
            raise UserInputError(f"experiment.cube_voxels={e.cube_voxels:g} makes the objects larger than the "
                                 f"{G}^3 map holds in every orientation (at most {most:.2f} voxels per cube edge, "
                                 "the scale rule): rotations would carry them out of the map and no comparison "
                                 "would be decided")
    _probe(e, built[0])


def _probe(e, cells) -> None:
    """Render the first training object once, in the general view; refuse when no pixel of it is
    redder than ``view.red_threshold``."""
    from ...core.native import quiet_native_output
    from ...vision import shepard_metzler as sm
    from .data import make_scene

    with quiet_native_output():  # pybullet's banner on import: a refusal stays one line
        import pybullet  # noqa: F401
    scene = make_scene(e)
    try:
        view = scene.look(sm.centred(cells), sm.pose(None, 0, e.view.tilt_deg, e.view.turn_deg))
    finally:
        scene.close()
    b, g, r = (view.bgr[..., k].astype(np.float32) for k in range(3))
    redness = r - np.maximum(g, b)
    if not (redness > e.view.red_threshold).any():
        raise UserInputError(f"experiment.view.red_threshold={e.view.red_threshold:g}: no pixel of the object is that red "
                             f"(R - max(G, B) reaches {float(redness.max()):.0f} in a probe view); lower it")
