"""Shepard-Metzler objects (Shepard & Metzler, 1971) built in pybullet and seen by the iCub's eye.

An object is a list of unit-cube cells on the integer lattice, joined face to face into arms with
right-angled elbows. The procedural generator (:func:`generate`) follows a fixed rule:

* ten cubes in four straight arms joined by three elbows; every elbow turns at a right angle to
  the arm before it, and the arms use all three lattice directions (the object is not flat);
* no cube repeats; the object is chiral: its mirror image matches none of the 24 rotations of
  the cube group (up to translation, :func:`is_chiral`);
* the mirror differs from the object by at least ``min_margin`` cubes: at every proper rotation of
  the cube group and every lattice shift it leaves that many of the object's cubes uncovered
  (:func:`mirror_margin`; 1 = chirality alone);
* candidates are drawn from a generator seeded by ``seed`` and kept in the order drawn, skipping
  any that equals an earlier one under a rotation or a reflection.

The mirror object (:func:`mirror`) is the reflection of the cube centres along the lattice axis
of least spread, through the centroid (a lattice reflection, so the cubes stay face to face; any
reflection gives the same enantiomer up to a rotation).

Views (:class:`SMScene`): the object, centred at ``distance`` metres straight ahead of the chosen
eye at eye height, is turned first to a fixed general view ``R0`` (tilted toward the eye by
``view_tilt_deg`` about the horizontal axis, then turned by ``view_turn_deg`` about the vertical
axis, so no face is seen edge on) and then by the trial's rotation: about the line of sight
(``picture``) or about the vertical axis (``depth``). Camera axes (right-handed): x to the eye's
right, y up, z along the line of sight toward the eye. The eye pose comes from the iCub head chain of
:mod:`neuroimagery.vision.camera`; pybullet's TinyRenderer returns colour and depth.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np

from ..core.files import save_figure

__all__ = ["generate", "mirror", "is_chiral", "mirror_margin", "check_object", "canonical", "rotation_matrix", "SMScene",
           "View", "contact_sheet", "KINDS"]

KINDS = ("picture", "depth")  # rotation about the line of sight / about the vertical axis
RED = (0.85, 0.08, 0.08)


# ------------------------------------------------------------------------- lattice objects
@lru_cache(maxsize=1)
def _cube_group() -> np.ndarray:
    """The 24 proper rotations of the cube as integer 3x3 matrices."""
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            m = np.zeros((3, 3), int)
            for i, (j, s) in enumerate(zip(perm, signs)):
                m[i, j] = s
            if round(np.linalg.det(m)) == 1:
                mats.append(m)
    return np.stack(mats)


def canonical(cells: np.ndarray) -> tuple:
    """A hashable form of a cell set up to translation (sorted, shifted to the origin)."""
    c = np.asarray(cells, int)
    c = c - c.min(0)
    return tuple(sorted(map(tuple, c.tolist())))


def _rotations(cells: np.ndarray) -> set:
    return {canonical(np.asarray(cells) @ m.T) for m in _cube_group()}


def is_chiral(cells: np.ndarray) -> bool:
    """True when the lattice reflection of ``cells`` equals none of its 24 rotations."""
    refl = np.asarray(cells, int) * np.array([-1, 1, 1])
    return canonical(refl) not in _rotations(cells)


def mirror_margin(cells: np.ndarray) -> int:
    """Cubes of ``cells`` that its mirror image leaves uncovered at its best proper correspondence:
    the least, over the 24 rotations of the cube group and every lattice shift that puts a cube of
    the turned mirror on a cube of the object, of the object's cubes the mirror does not cover
    (0 exactly when the object is its own mirror image)."""
    c = np.asarray(cells, int)
    G = _cube_group()
    r = np.einsum("gij,nj->gni", G, c * np.array([-1, 1, 1]))  # (24, n, 3) the mirror, turned
    shifts = (c[None, :, None, :] - r[:, None, :, :]).reshape(len(G), -1, 3)  # cube j of r onto cube i of c
    placed = r[:, None, :, :] + shifts[:, :, None, :]  # (24, shifts, n, 3)
    lo = c.min(0) - 4 * len(c)

    def key(x):
        x = x - lo
        return (x[..., 0] * 1024 + x[..., 1]) * 1024 + x[..., 2]

    return len(c) - int(np.isin(key(placed), key(c)).sum(-1).max())


def _too_close(cells: np.ndarray, min_margin: int) -> int | None:
    """The mirror margin of ``cells`` when it is under ``min_margin`` (a chiral object always has 1,
    so it is computed only for ``min_margin > 1``), else None."""
    if min_margin <= 1:
        return None
    m = mirror_margin(cells)
    return m if m < min_margin else None


def check_object(cells, name: str = "object", min_margin: int = 1) -> np.ndarray:
    """Validate a user's cube list: distinct integer cells, face-connected, at least 4, chiral, its
    mirror differing from it by at least ``min_margin`` cubes (:func:`mirror_margin`).
    Returns ``(n, 3)`` int cells; raises ``ValueError`` naming the problem."""
    try:
        c = np.asarray(cells, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a list of [x, y, z] integer cube positions") from None
    if c.ndim != 2 or c.shape[1] != 3 or len(c) < 4:
        raise ValueError(f"{name}: must be a list of at least 4 [x, y, z] cube positions, got shape {c.shape}")
    if not np.all(np.isfinite(c)) or not np.all(c == np.round(c)):
        raise ValueError(f"{name}: cube positions must be integers")
    c = c.astype(int)
    if len({tuple(r) for r in c.tolist()}) != len(c):
        raise ValueError(f"{name}: a cube position repeats")
    seen, todo, cellset = {tuple(c[0])}, [tuple(c[0])], {tuple(r) for r in c.tolist()}
    while todo:
        x = todo.pop()
        for d in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
            y = (x[0] + d[0], x[1] + d[1], x[2] + d[2])
            if y in cellset and y not in seen:
                seen.add(y)
                todo.append(y)
    if len(seen) != len(c):
        raise ValueError(f"{name}: the cubes are not joined face to face into one object")
    if not is_chiral(c):
        raise ValueError(f"{name}: the object equals its own mirror image (a rotation maps one onto the other), "
                         "so same and mirror pairs could not differ")
    margin = _too_close(c, min_margin)
    if margin is not None:
        raise ValueError(f"{name}: its mirror image differs from it by only {margin} cube(s) at its best "
                         f"proper correspondence; the stimulus rule asks for at least {min_margin} "
                         "(experiment.mirror_cubes; 1 = chirality alone)")
    return c


def _axes() -> list[np.ndarray]:
    return [np.array(v) for v in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]


def _candidate(rng: np.random.Generator, cubes: int, arms: int) -> np.ndarray | None:
    moves = cubes - 1
    # arm lengths (moves per arm) >= 1 summing to cubes - 1, drawn uniformly among compositions
    cuts = np.sort(rng.choice(np.arange(1, moves), size=arms - 1, replace=False))
    lengths = np.diff(np.concatenate([[0], cuts, [moves]]))
    if lengths.min() < 2 and arms * 2 <= moves:
        return None  # arms of at least two cubes' length when there is room: each arm reads as an arm
    dirs, prev = [], None
    for _ in range(arms):
        options = [a for a in _axes() if prev is None or int(abs(a @ prev)) == 0]
        d = options[rng.integers(len(options))]
        dirs.append(d)
        prev = d
    if len({int(np.argmax(np.abs(d))) for d in dirs}) < 3:
        return None  # flat objects are their own mirror images
    cells = [np.zeros(3, int)]
    for d, n in zip(dirs, lengths):
        for _ in range(int(n)):
            cells.append(cells[-1] + d)
    c = np.stack(cells)
    if len({tuple(r) for r in c.tolist()}) != len(c):
        return None
    return c


def generate(n: int, seed: int = 0, cubes: int = 10, arms: int = 4, min_margin: int = 1) -> list[np.ndarray]:
    """``n`` distinct chiral objects of ``cubes`` cubes in ``arms`` arms whose mirror differs from
    them by at least ``min_margin`` cubes (rule: module docstring)."""
    if n < 1 or cubes < 4 or not (2 <= arms <= cubes - 1):
        raise ValueError(f"need n >= 1, cubes >= 4, 2 <= arms < cubes; got {n}, {cubes}, {arms}")
    rng = np.random.default_rng(seed)
    out, seen = [], set()
    for _ in range(100_000):
        c = _candidate(rng, cubes, arms)
        if c is None or not is_chiral(c) or _too_close(c, min_margin) is not None:
            continue
        forms = _rotations(c) | _rotations(c * np.array([-1, 1, 1]))
        if forms & seen:
            continue
        seen |= forms
        out.append(c)
        if len(out) == n:
            return out
    raise ValueError(f"could not find {n} distinct chiral objects of {cubes} cubes in {arms} arms"
                     + (f" whose mirror differs by at least {min_margin} cubes" if min_margin > 1 else ""))


def centred(cells: np.ndarray) -> np.ndarray:
    """Cube centres (float) relative to the object's centroid."""
    c = np.asarray(cells, float)
    return c - c.mean(0)


def mirror(cells: np.ndarray) -> np.ndarray:
    """Centred cube centres of the mirror object: reflection along the lattice axis of least spread
    (the first such axis on ties), through the centroid."""
    x = centred(cells)
    k = int(np.argmin(x.var(0) + 1e-9 * np.arange(3)))
    x = x.copy()
    x[:, k] = -x[:, k]
    return x


def rotation_matrix(axis: str, deg: float) -> np.ndarray:
    """Right-handed rotation by ``deg`` about camera axis ``x``, ``y`` or ``z``."""
    t = math.radians(deg)
    c, s = math.cos(t), math.sin(t)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    if axis == "z":
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    raise ValueError(f"axis must be x, y or z, got {axis!r}")


KIND_AXIS = {"picture": "z", "depth": "y"}
# an extra test (not one of Shepard & Metzler's): turns about an oblique axis, between all three camera axes
OBLIQUE_AXIS = np.array([1.0, 1.0, 1.0]) / math.sqrt(3.0)


def rotation_about(axis, deg: float) -> np.ndarray:
    """Right-handed rotation by ``deg`` about a unit vector ``axis`` (Rodrigues)."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    t = math.radians(deg)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * K @ K


def random_chains(n: int, rng: np.random.Generator, exclude=(), max_radius: float | None = None,
                  cubes: int = 10, arms=(3, 4, 5), min_margin: int = 1) -> list[np.ndarray]:
    """``n`` random chains of ``cubes`` face-joined cubes in straight arms (the rule of
    :func:`generate` with ``arms`` drawn from ``arms``), chiral, their mirror differing from them by
    at least ``min_margin`` cubes, none equal under a rotation or a
    reflection to an object of ``exclude``, none reaching further than ``max_radius`` cube edges
    (cube centre plus half a diagonal) from its centroid. Draws only from ``rng``."""
    banned = set()
    for c in exclude:
        banned |= _rotations(c) | _rotations(np.asarray(c) * np.array([-1, 1, 1]))
    out = []
    for _ in range(200 * n + 1000):
        c = _candidate(rng, cubes, int(arms[rng.integers(len(arms))]))
        if c is None or not is_chiral(c) or canonical(c) in banned:
            continue
        if _too_close(c, min_margin) is not None:
            continue
        if max_radius is not None and np.linalg.norm(centred(c), axis=1).max() + math.sqrt(3) / 2 > max_radius:
            continue
        out.append(c)
        if len(out) == n:
            return out
    raise ValueError(f"could not draw {n} random chains of {cubes} cubes")


def pose(kind: str | None, deg: float, tilt_deg: float, turn_deg: float) -> np.ndarray:
    """Rotation (camera frame) of an object shown at ``deg`` of rotation ``kind`` from the general view."""
    r0 = rotation_matrix("y", turn_deg) @ rotation_matrix("x", tilt_deg)
    if kind is None or deg == 0:
        return r0
    if kind == "oblique":
        return rotation_about(OBLIQUE_AXIS, deg) @ r0
    if kind not in KIND_AXIS:
        raise ValueError(f"rotation kind must be one of {KINDS + ('oblique',)}, got {kind!r}")
    return rotation_matrix(KIND_AXIS[kind], deg) @ r0


# ------------------------------------------------------------------------- the scene
@dataclass
class View:
    """What the eye sees of one object: colour ``(H, W, 3)`` BGR uint8 and metric depth ``(H, W)``
    along the optical axis, with the camera intrinsics needed to back-project pixels."""

    bgr: np.ndarray
    depth: np.ndarray
    focal_px: float


class SMScene:
    """A pybullet DIRECT world holding one Shepard-Metzler object in front of the iCub's eye."""

    def __init__(self, eye: str = "left", width: int = 320, height: int = 240, fov_deg: float = 30.0,
                 distance: float = 0.5, cube_edge: float = 0.025, robot_model: str = "iCubGazeboV2_5") -> None:
        import pybullet as p
        import torch

        from .camera import eye_chain

        self.p, self.width, self.height, self.fov, self.cube = p, int(width), int(height), float(fov_deg), float(cube_edge)
        chain = eye_chain(robot_model)
        q0 = torch.zeros(len(chain.get_joint_parameter_names()), dtype=torch.float64)
        frames = chain.forward_kinematics(q0.reshape(1, -1))  # eyes straight ahead (tilt = pan = 0)
        tf = frames["l_eye" if eye == "left" else "r_eye"].get_matrix()[0].numpy()
        self.eye_pos, self.fwd, self.up = tf[:3, 3], tf[:3, 2], tf[:3, 1]
        self.right = np.cross(self.fwd, self.up)  # camera x in the world (robot root) frame
        self.centre = self.eye_pos + distance * self.fwd
        self.cam_to_world = np.stack([self.right, self.up, -self.fwd], axis=1)  # right-handed
        self.near, self.far = 0.05, 3.0
        self.client = p.connect(p.DIRECT)
        self.view = p.computeViewMatrix(self.eye_pos.tolist(), self.centre.tolist(), self.up.tolist(),
                                        physicsClientId=self.client)
        self.proj = p.computeProjectionMatrixFOV(self.fov, self.width / self.height, self.near, self.far,
                                                 physicsClientId=self.client)
        self.focal_px = 0.5 * self.height / math.tan(math.radians(self.fov) / 2)
        self._bodies: list[int] = []

    def _place(self, centres: np.ndarray, rot: np.ndarray) -> None:
        p, cid = self.p, self.client
        need = len(centres)
        while len(self._bodies) < need:
            vs = p.createVisualShape(p.GEOM_BOX, halfExtents=[self.cube / 2] * 3, rgbaColor=list(RED) + [1],
                                     physicsClientId=cid)
            self._bodies.append(p.createMultiBody(baseVisualShapeIndex=vs, basePosition=[0, 0, -10], physicsClientId=cid))
        world_rot = self.cam_to_world @ rot
        quat = _quaternion(world_rot)
        for k, body in enumerate(self._bodies):
            if k < need:
                pos = self.centre + self.cam_to_world @ (rot @ centres[k]) * self.cube
                p.resetBasePositionAndOrientation(body, pos.tolist(), quat, physicsClientId=cid)
            else:
                p.resetBasePositionAndOrientation(body, [0, 0, -10], [0, 0, 0, 1], physicsClientId=cid)

    def look(self, centres: np.ndarray, rot: np.ndarray) -> View:
        """Render the object with centred cube centres ``centres`` (cube units, object frame) turned
        by ``rot`` (camera frame): colour and metric depth."""
        p = self.p
        self._place(np.asarray(centres, float), np.asarray(rot, float))
        # the camera faces the robot's forward direction; a key light from above-left of the eye
        light = (self.eye_pos + 0.5 * self.up - 0.4 * self.right - self.centre)
        out = p.getCameraImage(self.width, self.height, self.view, self.proj, renderer=p.ER_TINY_RENDERER,
                               lightDirection=(light / np.linalg.norm(light)).tolist(), shadow=0,
                               lightAmbientCoeff=0.55, lightDiffuseCoeff=0.45, lightSpecularCoeff=0.0,
                               flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client)
        rgba = np.reshape(np.asarray(out[2], np.uint8), (self.height, self.width, 4))
        zbuf = np.reshape(np.asarray(out[3], np.float64), (self.height, self.width))
        depth = self.far * self.near / (self.far - (self.far - self.near) * zbuf)
        return View(np.ascontiguousarray(rgba[..., 2::-1]), depth, self.focal_px)

    def close(self) -> None:
        if self.p.isConnected(self.client):
            self.p.disconnect(self.client)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _quaternion(m: np.ndarray) -> list[float]:
    """(x, y, z, w) quaternion of a rotation matrix."""
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return [x, y, z, w]


def red_points(view: View, red_threshold: float = 60.0) -> np.ndarray:
    """Camera-frame 3-D points ``(n, 3)`` (metres; x right, y up, z toward the eye) of the red pixels
    of a view, back-projected with their depth."""
    b, g, r = (view.bgr[..., k].astype(np.float32) for k in range(3))
    mask = (r - np.maximum(g, b)) > red_threshold
    vs, us = np.nonzero(mask)
    h, w = view.depth.shape
    z = view.depth[vs, us]
    x = (us - (w - 1) / 2.0) * z / view.focal_px
    y = -(vs - (h - 1) / 2.0) * z / view.focal_px
    return np.stack([x, y, -z], axis=1)


def contact_sheet(scene: SMScene, objects: Sequence[np.ndarray], names: Sequence[str], path, angles=(0, 60, 120, 180),
                  tilt_deg: float = 25.0, turn_deg: float = 35.0) -> None:
    """A figure: one row per object, its view at each angle of each rotation kind, then its mirror."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = [(k, a, "same") for k in KINDS for a in angles] + [("picture", 0, "mirror")]
    fig, axes = plt.subplots(len(objects), len(cols), figsize=(1.4 * len(cols), 1.4 * len(objects)), squeeze=False)
    for i, (cells, name) in enumerate(zip(objects, names)):
        for j, (kind, a, app) in enumerate(cols):
            c = centred(cells) if app == "same" else mirror(cells)
            v = scene.look(c, pose(kind, a, tilt_deg, turn_deg))
            ax = axes[i, j]
            ax.imshow(v.bgr[..., ::-1])
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(f"{kind} {a}" if app == "same" else "mirror", fontsize=7)
            if j == 0:
                ax.set_ylabel(name, fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
