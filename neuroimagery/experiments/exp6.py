"""Experiment 6 (beyond the thesis): mental rotation of Shepard-Metzler objects in three
dimensions, seen by the iCub's eye. Model: :class:`neuroimagery.models.rotation_3d.Rotation3D`.

Protocol (docs/exp6.md): the forward models learn from random 3-D dot images turned by each move;
the posture maps learn the orientation of the views of the training objects; tests ``picture``
(rotation about the line of sight) and ``depth`` (about the vertical), 0-180 deg in 20-deg steps,
same or mirror pairs of the test objects, condition ``none``. RT = accumulator cycles.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, List, Optional

import numpy as np
import pandas as pd
import torch

from .. import progress
from ..errors import UserInputError
from ..models.rotation_embodied import PROPRIOCEPTION
from ..nn import seeding
from ..vision import shepard_metzler as sm
from .exp6_checks import check_inputs, memory_estimate  # noqa: F401  (checks before work: neuroimagery.validation)

TESTS = sm.KINDS  # picture, depth
CONDITIONS = PROPRIOCEPTION  # the wrist conditions, as Exp 4
WRIST_JOINTS = {"x": "r_wrist_pitch", "y": "r_wrist_yaw", "z": "r_wrist_prosup"}  # axis -> joint it stands for


@dataclass
class Exp6Config:
    name: str = "exp6"
    # --- stimuli (docs/exp6.md, "Stimulus rules") -------------------------------------------
    object_seed: int = 0  # seed of the object generator
    train_objects: int = 3  # first objects drawn: train the posture maps
    test_objects: int = 5  # next objects: the test set (never seen in training)
    test_cubes: Optional[List[Any]] = None  # own test objects: a list of lists of [x, y, z] cube positions
    # which objects the tests show: 'novel' = the test set (never seen in training) | 'train' = the
    # training objects themselves (as Exp 4's Recog test: the posture maps know these shapes)
    test_set: str = "novel"
    test_angles: List[float] = field(default_factory=lambda: [float(a) for a in range(0, 181, 20)])
    tests: List[str] = field(default_factory=lambda: ["picture", "depth"])
    # proprioception of Exp 4 carried over (docs/exp6.md): the wrist turns about the line of sight
    # while the pair is compared; 'none' = still, 'match' / 'mismatch' = its signal on the PPCp unit
    # of the mental image about that axis / on the opposite unit. Each condition runs every test.
    conditions: List[str] = field(default_factory=lambda: ["none"])
    view_tilt_deg: float = 25.0  # general view: tilted toward the eye about the horizontal ...
    view_turn_deg: float = 35.0  # ... then turned about the vertical
    cube_edge: float = 0.025  # metres
    object_distance: float = 0.5  # metres from the eye, straight ahead
    eye: str = "left"
    image_width: int = 320
    image_height: int = 240
    fov_deg: float = 30.0
    red_threshold: float = 60.0  # R - max(G, B) for a pixel to count as the object
    # --- the 3-D map ------------------------------------------------------------------------
    step_deg: float = 20.0  # one forward-model step
    fm_memory_mb: float = 24.0  # forward models of one participant: the grid rule (docs/exp6.md)
    grid: Optional[int] = None  # side of the voxel map; None = the grid rule
    cube_voxels: Optional[float] = None  # voxels per cube edge; None = the scale rule
    hidden: str = "surface"  # 'surface': the map holds what is seen | 'cube': seen points extended one cube behind
    # --- forward models (delta rule, eq. 6.4) -------------------------------------------------
    init_high: float = 0.01  # initial weights U[0, init_high] (as Exp 4)
    eta_fm: float = 0.1  # thesis 0.1
    fm_images: int = 84000  # dot images per participant, shared at random among the 7 moves (~20 per voxel per model)
    fm_batch: int = 32  # images per delta-rule update (changes at the same weights, summed; few share a voxel)
    # torch threads while the forward models and posture maps learn (at most the run's): their updates
    # are many small operations, which several threads slow down (speed only)
    train_threads: int = 1
    # --- posture maps (supervised Kohonen, eq. 6.14-6.16) -------------------------------------
    posture_angles: List[float] = field(default_factory=lambda: [float(a) for a in range(0, 181, 20)])
    eta_posture: float = 0.1  # thesis 0.1
    posture_sigma: float = 0.3  # neighbourhood of the forced winner, units (as Exp 4)
    posture_iterations: int = 1440  # supervised steps (as Exp 4)
    ppc_sigma: float = 0.5  # bump width around the winner (as Exp 4)
    # posture read-out: 'distance' = the nearest prototype (Euclidean, weights not normalised) |
    # 'dot' = eq. 6.14-6.16 (arg-max of W x, unit-sum weights); docs/choices.md gives the measured reason
    posture_readout: str = "distance"
    unreachable: str = "extend"  # orientations past the wrist's joint limits: 'extend' (virtual postures) | 'clip'
    # --- selection, matching, decision -------------------------------------------------------
    softmax_tau: float = 0.1  # thesis 0.1
    match_radius: int = 1  # PFCtm/PFCfm: POCp against the target's (2r+1)^3 neighbourhood; 0 = one-to-one
    lca_k: float = 0.5
    lca_w: float = 0.5  # thesis 0.5
    lca_threshold: float = 1.2  # thesis 1.2
    lca_dt: float = 0.1
    lca_cycles: int = 10  # thesis 10
    lca_input_gain: Optional[float] = None  # None = the Exp 4 rule
    max_steps: int = 20  # thesis 20
    proprio_gain: float = 1.0  # wrist signal strength (as Exp 4; not given)
    # --- protocol size -----------------------------------------------------------------------
    quick_objects: int = 2  # preset=quick: test objects
    quick_fm_images: int = 42000  # preset=quick: dot images (about 10 per voxel and model)

    def __post_init__(self) -> None:
        for k in ("view_tilt_deg", "view_turn_deg"):
            if not -90 <= getattr(self, k) <= 90:
                raise ValueError(f"experiment.{k} must lie in [-90, 90], got {getattr(self, k)!r}")
        if not self.conditions or len(set(self.conditions)) != len(self.conditions) or \
                any(c not in CONDITIONS for c in self.conditions) or "none" not in self.conditions:
            raise ValueError(f"experiment.conditions must be distinct names of {list(CONDITIONS)}, 'none' among them, "
                             f"got {self.conditions!r}")
        for k in ("proprio_gain", "cube_edge", "object_distance", "fov_deg", "step_deg", "fm_memory_mb", "init_high", "eta_fm", "eta_posture",
                  "posture_sigma", "ppc_sigma", "softmax_tau", "lca_threshold", "lca_dt", "red_threshold"):
            if not getattr(self, k) > 0:
                raise ValueError(f"experiment.{k} must be > 0, got {getattr(self, k)!r}")
        for k in ("lca_k", "lca_w", "match_radius", "object_seed"):
            if getattr(self, k) < 0:
                raise ValueError(f"experiment.{k} must be >= 0, got {getattr(self, k)!r}")
        for k in ("train_objects", "test_objects", "fm_images", "fm_batch", "train_threads", "posture_iterations", "lca_cycles", "max_steps",
                  "quick_objects", "quick_fm_images"):
            if int(getattr(self, k)) < 1:
                raise ValueError(f"experiment.{k} must be >= 1, got {getattr(self, k)!r}")
        if not 0 < self.step_deg <= 90:
            raise ValueError(f"experiment.step_deg must lie in (0, 90], got {self.step_deg}")
        if self.eye not in ("left", "right"):
            raise ValueError(f"experiment.eye must be 'left' or 'right', got {self.eye!r}")
        if not (64 <= self.image_width <= 2048 and 48 <= self.image_height <= 2048):
            raise ValueError("experiment.image_width/height must lie in [64, 2048] / [48, 2048]")
        if self.hidden not in ("surface", "cube"):
            raise ValueError(f"experiment.hidden must be 'surface' or 'cube', got {self.hidden!r}")
        if self.test_set not in ("novel", "train"):
            raise ValueError(f"experiment.test_set must be 'novel' or 'train', got {self.test_set!r}")
        if self.posture_readout not in ("distance", "dot"):
            raise ValueError(f"experiment.posture_readout must be 'distance' or 'dot', got {self.posture_readout!r}")
        if self.unreachable not in ("extend", "clip"):
            raise ValueError(f"experiment.unreachable must be 'extend' or 'clip', got {self.unreachable!r}")
        bad = [t for t in self.tests if t not in TESTS]
        if bad or not self.tests:
            raise ValueError(f"experiment.tests: unknown or none {bad}; choose from {list(TESTS)}")
        if self.grid is not None and (self.grid < 8 or self.grid % 2):
            raise ValueError(f"experiment.grid must be an even number >= 8 (or null for the rule), got {self.grid}")
        if self.cube_voxels is not None and not self.cube_voxels > 0:
            raise ValueError(f"experiment.cube_voxels must be > 0 (or null for the rule), got {self.cube_voxels}")
        if self.lca_input_gain is not None and not self.lca_input_gain > 0:
            raise ValueError(f"experiment.lca_input_gain must be > 0 (or null), got {self.lca_input_gain}")
        if len(self.posture_angles) < 2 or list(self.posture_angles) != sorted(self.posture_angles):
            raise ValueError("experiment.posture_angles must be >= 2 increasing angles")
        if any(not 0 <= a <= 180 for a in self.test_angles) or not self.test_angles:
            raise ValueError("experiment.test_angles must be angles in [0, 180]")
        if self.test_cubes is not None:
            if not isinstance(self.test_cubes, (list, tuple)) or not self.test_cubes:
                raise ValueError("experiment.test_cubes must be a list of objects, each a list of [x, y, z] cubes")
            for i, c in enumerate(self.test_cubes):
                sm.check_object(c, f"experiment.test_cubes[{i}]")


CONFIG = Exp6Config
INPUTS = ()  # the eye camera of this experiment is set by its own keys (eye, fov_deg, image_*)
CHECKPOINTS = ("exp6",)
TEST_KEYS = ("test_objects", "test_cubes", "test_set", "test_angles", "tests", "conditions", "proprio_gain", "softmax_tau", "match_radius", "lca_k", "lca_w",
             "lca_threshold", "lca_dt", "lca_cycles", "lca_input_gain", "max_steps", "quick_objects")
RUNTIME_KEYS = ("train_threads",)


def ineffective_keys(cfg) -> dict[str, str]:
    e, out = cfg.experiment, {}
    if e.test_cubes is not None:
        out["test_objects"] = "test_cubes replaces the built-in test set"
        out["quick_objects"] = "test_cubes replaces the built-in test set"
        out["test_set"] = "test_cubes replaces the built-in test set"
    elif e.test_set == "train":
        out["test_objects"] = "test_set=train shows the training objects"
    if cfg.preset == "quick":
        out["fm_images"] = "preset=quick trains on quick_fm_images"
    if e.grid is not None:
        out["fm_memory_mb"] = "grid is set, so the grid rule is not used"
    return {f"experiment.{k}": v for k, v in out.items()}


# ------------------------------------------------------------------------------ geometry
def grid_side(e) -> int:
    from ..models.rotation_3d import grid_for_budget

    return int(e.grid) if e.grid is not None else grid_for_budget(e.fm_memory_mb, e.step_deg)


def objects(e) -> tuple[list[np.ndarray], list[str], list[np.ndarray], list[str]]:
    """(training objects, names, test objects, names)."""
    built = sm.generate(e.train_objects + e.test_objects, seed=e.object_seed)
    train, test = built[:e.train_objects], built[e.train_objects:]
    tnames = [f"T{i + 1}" for i in range(len(train))]
    if e.test_cubes is not None:
        test = [sm.check_object(c, f"experiment.test_cubes[{i}]") for i, c in enumerate(e.test_cubes)]
        return train, tnames, test, [f"U{i + 1}" for i in range(len(test))]
    if e.test_set == "train":
        return train, tnames, list(train), list(tnames)
    return train, tnames, test, [f"S{i + 1}" for i in range(len(test))]


def cube_voxels(e, side: int) -> float:
    """Voxels per cube edge: ``e.cube_voxels``, or the largest scale at which every built-in object
    (cube centres plus half a cube diagonal) fits the dot ball (radius G/2 - 1.5) in every orientation."""
    if e.cube_voxels is not None:
        return float(e.cube_voxels)
    built = sm.generate(e.train_objects + e.test_objects, seed=e.object_seed)
    rho = max(float(np.linalg.norm(sm.centred(c), axis=1).max()) for c in built) + math.sqrt(3) / 2
    return (side / 2.0 - 1.5) / rho


def make_scene(e) -> sm.SMScene:
    return sm.SMScene(eye=e.eye, width=e.image_width, height=e.image_height, fov_deg=e.fov_deg,
                      distance=e.object_distance, cube_edge=e.cube_edge)


def view_map(scene, e, side: int, scale: float, cells: np.ndarray, appearance: str, rot: np.ndarray) -> torch.Tensor:
    """The 3-D map of one object (``basic`` or ``mirror``) seen turned by ``rot`` (camera frame)."""
    from ..models import voxels

    c = sm.centred(cells) if appearance == "basic" else sm.mirror(cells)
    pts = sm.red_points(scene.look(c, rot), e.red_threshold)
    if len(pts) == 0:
        raise UserInputError("exp6: the eye sees no red pixels of an object (is it in the field of view?)")
    vox = e.cube_edge / scale
    if e.hidden == "cube":
        return voxels.points_to_map(pts, side, vox, extend=e.cube_edge, steps=max(1, int(math.ceil(scale))))
    return voxels.points_to_map(pts, side, vox)


def see(scene, e, side: int, scale: float, cells: np.ndarray, appearance: str, kind, angle: float) -> torch.Tensor:
    """The 3-D map of one test view: ``angle`` deg of rotation ``kind`` from the general view."""
    return view_map(scene, e, side, scale, cells, appearance, sm.pose(kind, angle, e.view_tilt_deg, e.view_turn_deg))


# ------------------------------------------------------------------------------ training
def _model(cfg, ids):
    from ..models.rotation_3d import Rotation3D

    return Rotation3D(cfg.experiment, grid_side(cfg.experiment), seeding.participant_generators(cfg.seed, ids, stream=0))


@lru_cache(maxsize=2)
def wrist_limits(robot_model: str = "iCubGazeboV2_5") -> dict[str, tuple[float, float]]:
    """Joint limits (deg) of the wrist joint each rotation axis stands for, read from the iCub URDF."""
    import xml.etree.ElementTree as ET

    from ..robot.kinematics import icub_urdf_text

    root = ET.fromstring(icub_urdf_text(robot_model, keep_geometry=False))
    by = {}
    for j in root.findall("joint"):
        lim = j.find("limit")
        if j.get("name") in WRIST_JOINTS.values() and lim is not None:
            by[j.get("name")] = (math.degrees(float(lim.get("lower"))), math.degrees(float(lim.get("upper"))))
    return {a: by[n] for a, n in WRIST_JOINTS.items()}


def posture_label(e, axis: str, angle: float, limits) -> int:
    """Posture unit of a view turned by ``angle`` about ``axis`` (nearest unit; 'clip' stops at the limit)."""
    a = float(angle)
    if e.unreachable == "clip":
        lo, hi = limits[axis]
        a = min(max(a, lo), hi)
    return int(np.argmin([abs(a - u) for u in e.posture_angles]))


def posture_views(e, scene, side, scale, train, limits):
    """Views of the training objects turned about each axis by each posture angle, with labels
    ``(N, 3)`` (the unit per axis map)."""
    from ..models.rotation_3d import AXES

    maps, labels = [], []
    r0 = sm.pose(None, 0, e.view_tilt_deg, e.view_turn_deg)
    for cells in train:
        for app in ("basic", "mirror"):
            for a, axis in enumerate(AXES):
                for ang in e.posture_angles:
                    maps.append(view_map(scene, e, side, scale, cells, app, sm.rotation_matrix(axis, ang) @ r0))
                    lab = [posture_label(e, ax, 0.0, limits) if ax != axis else posture_label(e, axis, ang, limits) for ax in AXES]
                    labels.append(lab)
    return torch.stack(maps), torch.tensor(labels, dtype=torch.long)


def dot_training(model, gens, n_img: int, batch: int) -> None:
    """Delta rule on 3-D dot images: each image's move drawn at random, the target its warp. The
    images are handed to ``Connection.learn`` by their active voxels (the rule's index form)."""
    from ..models import voxels

    side, P = model.side, len(gens)
    targets = [voxels.warp_targets(voxels.warp_index(side, ax, deg)) for ax, deg in model.moves]
    D = torch.stack([voxels.dot_indices(n_img, side, g) for g in gens])  # (P, N, 3)
    M = torch.stack([torch.randint(len(targets), (n_img,), generator=g) for g in gens])  # (P, N)
    for m, conn in enumerate(progress.bar(model.fm, what="forward models", unit="move")):
        rows = [(M[k] == m).nonzero().squeeze(-1) for k in range(P)]
        L = max(int(r.numel()) for r in rows)
        Dm = torch.full((P, L, D.shape[-1]), -1, dtype=torch.long)  # padded with empty images
        for k, r in enumerate(rows):
            Dm[k, :r.numel()] = D[k, r]
        Tm = targets[m][torch.where(Dm < 0, side ** 3, Dm)].reshape(P, L, -1)
        for s in range(0, L, batch):
            conn.learn(pre_index=Dm[:, s:s + batch], target_index=Tm[:, s:s + batch])


def train_model(cfg, ids, scene=None):
    """Train participants ``ids`` (a batched run equals their solo runs)."""
    e = cfg.experiment
    model = _model(cfg, ids)
    gens = seeding.participant_generators(cfg.seed, ids, stream=1)
    n_img = e.quick_fm_images if cfg.preset == "quick" else e.fm_images
    model.train()
    from ..nn.functional import intra_op_threads

    with intra_op_threads(e.train_threads, cap=True):
        dot_training(model, gens, n_img, e.fm_batch)
    own = scene is None
    scene = make_scene(e) if own else scene
    try:
        side = model.side
        train, _, _, _ = objects(e)
        limits = wrist_limits()
        X, labels = posture_views(e, scene, side, cube_voxels(e, side), train, limits)
    finally:
        if own:
            scene.close()
    with intra_op_threads(e.train_threads, cap=True):
        for a in range(3):
            for som in (model.c16[a], model.c17[a]):
                som.fit(X, labels=labels[:, a], generators=gens, method="factored")
    model.eval()
    model.participant_ids = list(ids)
    return model


def train(cfg, run):
    ids = list(range(cfg.participants))
    model = train_model(cfg, ids)
    run.save_checkpoint("exp6", {"state_dict": model.state_dict(), "participants": list(ids)})
    return model


def load(cfg, checkpoint_dir):
    from ..run import load_checkpoint

    ck = load_checkpoint(checkpoint_dir, "exp6")
    model = _model(cfg, ck["participants"])
    model.load_state_dict(ck["state_dict"])
    model.eval()
    model.participant_ids = list(ck["participants"])
    return model


# ------------------------------------------------------------------------------ tests
def stimulus_bank(cfg, scene, side: int):
    """Maps of every test view: ``(maps (N, n), index {(object, kind, angle, appearance): row}, names, cells)``."""
    e = cfg.experiment
    _, _, test, names = objects(e)
    if cfg.preset == "quick" and e.test_cubes is None:
        test, names = test[:e.quick_objects], names[:e.quick_objects]
    scale = cube_voxels(e, side)
    maps, index = [], {}
    for cells, name in zip(test, names):
        for app in ("basic", "mirror"):
            for kind in e.tests:
                for ang in e.test_angles:
                    key = (name, kind, float(ang), app)
                    if (name, None, 0.0, app) in index and ang == 0:
                        index[key] = index[(name, None, 0.0, app)]
                        continue
                    index[key] = len(maps)
                    if ang == 0:
                        index[(name, None, 0.0, app)] = len(maps)
                    maps.append(see(scene, e, side, scale, cells, app, kind, ang))
    return torch.stack(maps), index, names, test


def trial_table(index, names, e, test: str, condition: str = "none") -> pd.DataFrame:
    """One row per pair of a test: the target in the general view, the comparison turned by each angle."""
    rows = []
    for name in names:
        for app in ("basic", "mirror"):
            for ang in e.test_angles:
                rows.append({"test": test, "condition": condition, "target_object": name, "target_angle": 0.0,
                             "target_appearance": "basic", "rotated_object": name, "rotated_angle": float(ang),
                             "rotated_appearance": app, "same": app == "basic",
                             "target_row": index[(name, test, 0.0, "basic")], "rotated_row": index[(name, test, float(ang), app)]})
    df = pd.DataFrame(rows)
    df["disparity"] = df["rotated_angle"].round().astype(int)
    return df


def rotated_ok(kind: str, angle: np.ndarray, turned: np.ndarray, step: float) -> np.ndarray:
    """The mental rotation undid the stimulus's: about the rotation's axis by -angle (mod 360), and
    zero about the other two axes."""
    from ..models.rotation_3d import AXES

    ax = AXES.index(sm.KIND_AXIS[kind])
    want = np.zeros_like(turned)
    want[:, ax] = -angle
    d = (turned - want + 180.0) % 360.0 - 180.0
    return (np.abs(d) < step / 2).all(1)


def run_tests(cfg, model, scene=None, record: int = 0):
    """Every test -> (trials DataFrame, sample histories, bank maps)."""
    from ..analysis.summary import TRIAL_COLUMNS

    e = cfg.experiment
    own = scene is None
    scene = make_scene(e) if own else scene
    try:
        maps, index, names, _ = stimulus_bank(cfg, scene, model.side)
    finally:
        if own:
            scene.close()
    ids = getattr(model, "participant_ids", list(range(model.participants)))[:model.participants]
    P = model.participants
    frames, histories = [], {}
    for k, test in enumerate(e.tests):
        for cond in e.conditions:
            table = trial_table(index, names, e, test, cond)
            tgt = maps[torch.as_tensor(table["target_row"].to_numpy().copy())].unsqueeze(0).expand(P, -1, -1)
            rot = maps[torch.as_tensor(table["rotated_row"].to_numpy().copy())].unsqueeze(0).expand(P, -1, -1)
            stream = 100 + k + 10 * CONDITIONS.index(cond)  # condition none keeps the stream of a run without the others
            out = model.run(tgt, rot, seeding.participant_generators(cfg.seed, ids, stream=stream), record=record,
                            proprioception=cond)
            histories[f"{test}/{cond}"] = out.pop("history")
            for j, pid in enumerate(ids):
                df = table.drop(columns=["target_row", "rotated_row"]).copy()
                df.insert(0, "participant", int(pid))
                df["answer"] = np.where(out["answer"][j].numpy() == 0, "yes", "no")
                df["correct"] = (df["answer"] == "yes") == df["same"].astype(bool)
                df["rotation_steps"] = out["rotation_steps"][j].numpy().astype(int)
                df["rotated_ok"] = rotated_ok(test, df["rotated_angle"].to_numpy(), out["turned"][j].numpy(), e.step_deg)
                df["rt"] = out["rt"][j].numpy()
                df["decided"] = out["decided"][j].numpy()
                frames.append(df[TRIAL_COLUMNS + ["decided"]])
            progress.advance(len(table) * P, note=f"{test}/{cond}")
    return pd.concat(frames, ignore_index=True), histories, maps


def effects(df: pd.DataFrame) -> list[dict]:
    """Shepard & Metzler's effects and, with wrist conditions, the proprioception effects
    (``exp6_report.effects``), the participant as the unit; also used when runs are pooled."""
    from . import exp6_report

    return exp6_report.effects(df)


def evaluate(cfg, run, trained) -> dict:
    from . import exp6_report

    return exp6_report.evaluate(cfg, run, trained)


def report(cfg, run, summary) -> None:
    from . import exp6_report

    exp6_report.report(cfg, run, summary)
