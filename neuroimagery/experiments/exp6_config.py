"""Experiment 6's configuration (``experiment=exp6``): the stimulus keys at the top level and one
group per stage (docs/exp6.md). Groups shared in meaning with Experiment 4: ``fm`` (forward
models: ``eta``, ``images``, ``batch``), ``lca`` (the accumulator PMCd: Exp 4's ``lca_*`` keys)
and ``quick``; the top-level ``step_deg``, ``ppc_sigma``, ``softmax_tau``, ``max_steps``,
``proprio_gain`` and ``conditions`` mean what they mean there."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, List, Optional

from ..bounds import bounded, check_declared
from ..models.rotation_embodied import PROPRIOCEPTION
from ..vision import shepard_metzler as sm

TESTS = sm.KINDS + ("oblique",)  # picture, depth, and the extra test about an oblique axis
CONDITIONS = PROPRIOCEPTION


@dataclass
class ImageParams:
    """Stage 1 (``experiment.image``): the graded code and the completion map C_fill."""

    sigma: float = bounded(0.7, gt=0)  # tuning width of a voxel unit (voxels)
    # C_fill reads this many voxels toward the eye (and one behind); -1 = no completion (the seen surface alone)
    fill_depth: int = bounded(9, ge=-1)
    lateral: int = bounded(1, ge=0)  # ... and the voxels up to this far beside that line
    eta: float = bounded(0.002, gt=0, le=1)  # delta-rule rate of C_fill (with the batch: a stable step for receptive fields of ~50 active units)
    chains: int = bounded(1200, ge=1)  # views of random cube chains in random poses (one set per run, each participant its own order)
    batch: int = bounded(8, ge=1)  # views per delta-rule update

    def __post_init__(self) -> None:
        check_declared(self, "experiment.image.")


@dataclass
class FMParams:
    """Stage 2 (``experiment.fm``): the forward models (delta rule, eq. 6.4) on graded dots."""

    eta: float = bounded(0.1, gt=0, le=1)  # thesis 0.1
    images: int = bounded(200, ge=1)  # training images per move and participant
    batch: int = bounded(4, ge=1)  # images per delta-rule update
    dots: int = bounded(24, ge=1)  # graded dots at sub-voxel positions per image, uniform in the dot ball
    memory_mb: float = bounded(20.0, gt=0)  # the forward models of one participant: the grid rule (docs/exp6.md)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.fm.")


@dataclass
class SearchParams:
    """Stage 3 (``experiment.search``): the correspondence that estimates the rotation required."""

    method: str = bounded("axes", choices=("axes", "sweep"))  # 'axes' = principal axes (Sanger's rule) + coarse comparison | 'sweep' = turns about x, y, z
    eta: float = bounded(0.5, gt=0, le=1)  # Sanger's rule, rate per update (divided by the inputs' mean squared norm)
    iterations: int = bounded(2000, ge=1)  # updates of the fast principal-axes connection per image (near-equal spreads converge slowly)
    coarse: int = bounded(2, ge=1)  # the coarse comparison pools blocks of coarse^3 voxels

    def __post_init__(self) -> None:
        check_declared(self, "experiment.search.")


@dataclass
class LcaParams:
    """PMCd, the leaky competing accumulator (``experiment.lca``; Exp 4's ``lca_*`` keys)."""

    k: float = 0.5  # leak
    w: float = 0.5  # mutual inhibition (thesis 0.5)
    threshold: float = 1.2  # thesis 1.2
    dt: float = 0.1
    cycles: int = bounded(10, ge=1)  # cycles per rotation step (thesis 10); the search takes as many
    input_gain: Optional[float] = bounded(None, gt=0)  # None = Exp 4's rule (a full match decides within one step's cycles)

    def __post_init__(self) -> None:
        from ..nn.decision import LeakyCompetingAccumulator
        from ..nn.functional import check_bounds

        keys = ("k", "w", "threshold", "dt")
        check_bounds({k: LeakyCompetingAccumulator.BOUNDS[k] for k in keys}, {k: getattr(self, k) for k in keys},
                     {k: f"experiment.lca.{k}" for k in keys})
        check_declared(self, "experiment.lca.")


@dataclass
class ConfirmParams:
    """Stage 4 (``experiment.confirm``): the mismatch after the transform."""

    level: float = bounded(0.5, gt=0, lt=1)  # a voxel mismatches when the turned image and the target differ by more than this

    def __post_init__(self) -> None:
        check_declared(self, "experiment.confirm.")


@dataclass
class QuickParams:
    """``preset=quick``: a first look (``experiment.quick``)."""

    objects: int = bounded(2, ge=1)  # test objects
    fm_images: int = bounded(100, ge=1)  # forward-model images per move
    chains: int = bounded(300, ge=1)  # chain views for C_fill

    def __post_init__(self) -> None:
        check_declared(self, "experiment.quick.")


@dataclass
class Exp6Config:
    name: str = "exp6"
    # --- stimuli (docs/exp6.md, "Stimulus rules") -------------------------------------------
    object_seed: int = 0  # seed of the object generator
    train_objects: int = 3  # first objects drawn: fix the confirm stage's cut
    test_objects: int = 5  # next objects: the test set (never seen in training)
    test_cubes: Optional[List[Any]] = None  # own test objects: a list of lists of [x, y, z] cube positions
    test_set: str = "novel"  # 'novel' = the test set | 'train' = the training objects
    test_angles: List[float] = field(default_factory=lambda: [float(a) for a in range(0, 181, 20)])
    oblique_angles: List[float] = field(default_factory=lambda: [10.0, 50.0, 90.0, 130.0, 170.0])  # test 'oblique'
    tests: List[str] = field(default_factory=lambda: ["picture", "depth"])
    conditions: List[str] = field(default_factory=lambda: ["none"])  # wrist conditions, as Exp 4
    view_tilt_deg: float = 25.0  # general view: tilted toward the eye about the horizontal ...
    view_turn_deg: float = 35.0  # ... then turned about the vertical
    cube_edge: float = 0.025  # metres
    object_distance: float = 0.5  # metres from the eye, straight ahead
    eye: str = "left"
    image_width: int = 320
    image_height: int = 240
    fov_deg: float = 30.0
    red_threshold: float = 60.0  # R - max(G, B) for a pixel to count as the object
    # --- the model ---------------------------------------------------------------------------
    strategy: str = bounded("rotate", choices=("rotate", "parity"))  # 'rotate' = search, transform, confirm | 'parity' = handedness of matched axes, no transform
    step_deg: float = 20.0  # one forward-model step
    grid: Optional[int] = None  # side of the voxel map; None = the grid rule (fm.memory_mb)
    cube_voxels: Optional[float] = None  # voxels per cube edge; None = the scale rule
    init_high: float = bounded(0.01, gt=0)  # initial weights U[0, init_high] (as Exp 4)
    image: ImageParams = field(default_factory=ImageParams)
    fm: FMParams = field(default_factory=FMParams)
    search: SearchParams = field(default_factory=SearchParams)
    ppc_sigma: float = bounded(0.5, gt=0)  # bump width of PPCt / PPCp, in units (as Exp 4)
    softmax_tau: float = bounded(0.1, gt=0)  # thesis 0.1
    max_steps: int = bounded(20, ge=1)  # thesis 20
    proprio_gain: float = bounded(1.0, gt=0)  # wrist signal strength (as Exp 4)
    lca: LcaParams = field(default_factory=LcaParams)
    confirm: ConfirmParams = field(default_factory=ConfirmParams)
    train_threads: int = bounded(1, ge=1)  # torch threads while the model learns (speed only)
    quick: QuickParams = field(default_factory=QuickParams)

    def __post_init__(self) -> None:
        for k in ("view_tilt_deg", "view_turn_deg"):
            if not -90 <= getattr(self, k) <= 90:
                raise ValueError(f"experiment.{k} must lie in [-90, 90], got {getattr(self, k)!r}")
        if not self.conditions or len(set(self.conditions)) != len(self.conditions) or \
                any(c not in CONDITIONS for c in self.conditions) or "none" not in self.conditions:
            raise ValueError(f"experiment.conditions must be distinct names of {list(CONDITIONS)}, 'none' among them, "
                             f"got {self.conditions!r}")
        check_declared(self, "experiment.", recursive=False)
        for k in ("cube_edge", "object_distance", "fov_deg", "step_deg", "red_threshold"):
            if not getattr(self, k) > 0:
                raise ValueError(f"experiment.{k} must be > 0, got {getattr(self, k)!r}")
        if self.object_seed < 0:
            raise ValueError(f"experiment.object_seed must be >= 0, got {self.object_seed!r}")
        for k in ("train_objects", "test_objects"):
            if int(getattr(self, k)) < 1:
                raise ValueError(f"experiment.{k} must be >= 1, got {getattr(self, k)!r}")
        if not 0 < self.step_deg <= 90 or abs(180.0 / self.step_deg - round(180.0 / self.step_deg)) > 1e-6:
            raise ValueError(f"experiment.step_deg must divide 180 and lie in (0, 90], got {self.step_deg}")
        if self.eye not in ("left", "right"):
            raise ValueError(f"experiment.eye must be 'left' or 'right', got {self.eye!r}")
        if not (64 <= self.image_width <= 2048 and 48 <= self.image_height <= 2048):
            raise ValueError("experiment.image_width/height must lie in [64, 2048] / [48, 2048]")
        if self.test_set not in ("novel", "train"):
            raise ValueError(f"experiment.test_set must be 'novel' or 'train', got {self.test_set!r}")
        bad = [t for t in self.tests if t not in TESTS]
        if bad or not self.tests:
            raise ValueError(f"experiment.tests: unknown or none {bad}; choose from {list(TESTS)}")
        if self.grid is not None and (self.grid < 8 or self.grid % 2):
            raise ValueError(f"experiment.grid must be an even number >= 8 (or null for the rule), got {self.grid}")
        if self.cube_voxels is not None and not self.cube_voxels > 0:
            raise ValueError(f"experiment.cube_voxels must be > 0 (or null for the rule), got {self.cube_voxels}")
        for k in ("test_angles", "oblique_angles"):
            v = getattr(self, k)
            if not v or any(not 0 <= a <= 180 for a in v):
                raise ValueError(f"experiment.{k} must be angles in [0, 180]")
        if self.test_cubes is not None:
            if not isinstance(self.test_cubes, (list, tuple)) or not self.test_cubes:
                raise ValueError("experiment.test_cubes must be a list of objects, each a list of [x, y, z] cubes")
            for i, c in enumerate(self.test_cubes):
                sm.check_object(c, f"experiment.test_cubes[{i}]")


_GONE = "removed; the rebuilt Experiment 6 (search, transform, confirm) has no such part: see docs/exp6.md"
MOVED = {"eta_fm": "fm.eta", "fm_images": "fm.images", "fm_batch": "fm.batch", "fm_memory_mb": "fm.memory_mb",
         "quick_objects": "quick.objects", "quick_fm_images": "quick.fm_images",
         **{f"lca_{k}": f"lca.{k}" for k in ("k", "w", "threshold", "dt", "cycles", "input_gain")},
         **{k: _GONE for k in ("hidden", "posture_angles", "eta_posture", "posture_sigma", "posture_iterations",
                               "posture_readout", "unreachable", "match_radius")}}
