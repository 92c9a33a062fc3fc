"""Experiment 6's configuration (``experiment=exp6``): the tests and the model's few global keys at
the top level; the stimuli in ``objects`` (what is shown) and ``view`` (how the eye sees it); one
group per stage (docs/exp6.md). Groups shared with Experiment 4 (:mod:`neuroimagery.models.params`):
``selection`` (the move's softmax and the steps before giving up; also Exp 3), ``lca`` (the
accumulator PMCd) and ``ppc`` (the posture bump and the wrist signal); ``fm`` and ``quick`` hold
keys of the same names and meanings as Exp 4's; the top-level ``step_deg``, ``init_high`` and
``conditions`` mean what they mean there. Every range check is declared (:mod:`neuroimagery.core.bounds`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, List, Optional

from ...core.bounds import Rule, bounded, check_declared
from ...models.params import LcaParams, PpcParams, SelectionParams
from ...models.rotation_embodied_params import PROPRIOCEPTION
from ...vision import shepard_metzler as sm

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
    images: int = bounded(3200, ge=1)  # training images per move and participant (the size rule, docs/choices.md)
    batch: int = bounded(4, ge=1)  # images per delta-rule update
    dots: int = bounded(24, ge=1)  # graded dots at sub-voxel positions per image, uniform in the dot ball
    memory_mb: float = bounded(20.0, gt=0)  # the forward models of one participant: the grid rule (docs/exp6.md)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.fm.")


@dataclass
class SearchParams:
    """Stage 3 (``experiment.search``): the correspondence that estimates the rotation required."""

    eta: float = bounded(0.5, gt=0, le=1)  # Sanger's rule, rate per update (divided by the inputs' mean squared norm)
    iterations: int = bounded(2000, ge=1)  # updates of the fast principal-axes connection per image (near-equal spreads converge slowly)
    coarse: int = bounded(2, ge=1)  # the coarse comparison pools blocks of coarse^3 voxels
    # local refinement of each matched-axes candidate by the same comparison: turns of these sizes (deg) about the
    # camera axes, each scale while the match rises, at most refine_steps times; [] = none
    refine: List[float] = bounded(factory=lambda: [10.0, 5.0, 2.5, 1.25], gt=0, each=True)
    refine_steps: int = bounded(3, ge=1)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.search.")


@dataclass
class ConfirmParams:
    """Stage 4 (``experiment.confirm``): the mismatch after the transform, the largest cluster of
    mismatching voxels (docs/choices.md)."""

    # a voxel mismatches when one of the turned image and the target is above this and the other is not
    level: float = bounded(0.5, gt=0, lt=1)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.confirm.")


@dataclass
class QuickParams:
    """``preset=quick``: a first look (``experiment.quick``)."""

    # the rule of docs/choices.md ("Quick presets"): the full protocol's training, a quarter of its participants
    participants: int = bounded(3, ge=1)  # a run tests the smaller of `participants` and this
    objects: int = bounded(1, ge=1)  # test objects (the first of objects.test): 5 halved twice by rule 3 (seed 0, CPU only)
    fm_images: int = bounded(3200, ge=1)  # forward-model images per move: the full protocol's (fm.images)
    chains: int = bounded(1200, ge=1)  # chain views for C_fill: the full protocol's (image.chains)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.quick.")


@dataclass
class ObjectParams:
    """The objects (``experiment.objects``, docs/exp6.md "Stimulus rules"): the generator's
    training and test objects, or the user's own test objects."""

    seed: int = bounded(0, ge=0)  # seed of the object generator
    # the mirror differs from the object, at its best proper lattice correspondence, by at least this many cubes
    # (built-in objects, random chains and test_cubes alike); 1 = chirality alone
    mirror_cubes: int = bounded(2, ge=1)
    train: int = bounded(3, ge=1)  # first objects drawn: fix the confirm stage's cut
    test: int = bounded(5, ge=1)  # next objects: the test set (never seen in training)
    test_cubes: Optional[List[Any]] = None  # own test objects: a list of lists of [x, y, z] cube positions
    test_set: str = bounded("novel", choices=("novel", "train"))  # 'novel' = the test set | 'train' = the training objects

    RULES = (
        Rule("test_cubes", lambda c: c.test_cubes is None or (isinstance(c.test_cubes, (list, tuple)) and c.test_cubes),
             "must be a list of objects, each a list of [x, y, z] cubes", show=False),
    )

    def __post_init__(self) -> None:
        check_declared(self, "experiment.objects.")
        for i, c in enumerate(self.test_cubes or ()):
            sm.check_object(c, f"experiment.objects.test_cubes[{i}]", self.mirror_cubes)


@dataclass
class ViewParams:
    """How the eye sees an object (``experiment.view``): the general view, the object's size and
    place, the eye camera and the red pixels that count as the object."""

    tilt_deg: float = bounded(25.0, ge=-90, le=90)  # general view: tilted toward the eye about the horizontal ...
    turn_deg: float = bounded(35.0, ge=-90, le=90)  # ... then turned about the vertical
    cube_edge: float = bounded(0.025, gt=0)  # metres
    object_distance: float = bounded(0.5, gt=0)  # metres from the eye, straight ahead
    eye: str = bounded("left", choices=("left", "right"))
    image_width: int = bounded(320, ge=64, le=2048)
    image_height: int = bounded(240, ge=48, le=2048)
    fov_deg: float = bounded(30.0, gt=0)
    red_threshold: float = bounded(60.0, gt=0)  # R - max(G, B) for a pixel to count as the object

    def __post_init__(self) -> None:
        check_declared(self, "experiment.view.")


@dataclass
class Exp6Config:
    name: str = "exp6"
    # --- the tests (docs/exp6.md, "Stimulus rules") -------------------------------------------
    test_angles: List[float] = bounded(factory=lambda: [float(a) for a in range(0, 181, 20)], ge=0, le=180, each=True,
                                       nonempty=True)
    oblique_angles: List[float] = bounded(factory=lambda: [10.0, 50.0, 90.0, 130.0, 170.0], ge=0, le=180, each=True,
                                          nonempty=True)  # test 'oblique'
    tests: List[str] = bounded(factory=lambda: ["picture", "depth"], choices=TESTS, each=True, nonempty=True)
    conditions: List[str] = bounded(factory=lambda: ["none"], choices=CONDITIONS, each=True)  # wrist conditions, as Exp 4
    objects: ObjectParams = field(default_factory=ObjectParams)
    view: ViewParams = field(default_factory=ViewParams)
    # --- the model ---------------------------------------------------------------------------
    strategy: str = bounded("rotate", choices=("rotate", "parity"))  # 'rotate' = search, transform, confirm | 'parity' = handedness of matched axes, no transform
    step_deg: float = bounded(20.0, gt=0, le=90)  # one forward-model step (divides 180)
    grid: Optional[int] = bounded(None, ge=8)  # side of the voxel map (even); None = the grid rule (fm.memory_mb)
    cube_voxels: Optional[float] = bounded(None, gt=0)  # voxels per cube edge; None = the scale rule
    init_high: float = bounded(0.01, gt=0)  # initial weights U[0, init_high] (as Exp 4)
    image: ImageParams = field(default_factory=ImageParams)
    fm: FMParams = field(default_factory=FMParams)
    search: SearchParams = field(default_factory=SearchParams)
    ppc: PpcParams = field(default_factory=PpcParams)  # PPCt / PPCp bump and wrist signal (as Exp 4)
    selection: SelectionParams = field(default_factory=SelectionParams)  # PMCm softmax, steps before giving up (as Exp 4)
    lca: LcaParams = field(default_factory=LcaParams)  # PMCd (as Exp 4; input_gain None = Exp 4's 'full' rule)
    confirm: ConfirmParams = field(default_factory=ConfirmParams)
    train_threads: int = bounded(1, ge=1)  # torch threads while the model learns (speed only)
    quick: QuickParams = field(default_factory=QuickParams)

    RULES = (
        Rule("conditions", lambda c: len(set(c.conditions)) == len(c.conditions) and "none" in c.conditions,
             f"must be distinct names of {list(CONDITIONS)}, 'none' among them"),
        Rule("step_deg", lambda c: abs(180.0 / c.step_deg - round(180.0 / c.step_deg)) <= 1e-6, "must divide 180"),
        Rule("grid", lambda c: c.grid is None or c.grid % 2 == 0, "must be an even number >= 8 (or null for the rule)"),
    )

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)


CONFIG = Exp6Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ()  # the eye camera of this experiment is set by its own keys (experiment.view)
CHECKPOINTS = ("exp6",)
TEST_KEYS = ("objects.test", "objects.test_cubes", "objects.test_set", "test_angles", "oblique_angles", "tests",
             "conditions", "ppc.proprio_gain", "selection.tau", "selection.max_steps", "strategy", "search.eta",
             "search.iterations", "search.coarse", "ppc.sigma", "lca.k", "lca.w", "lca.threshold", "lca.dt",
             "lca.cycles", "lca.input_gain", "quick.objects")
RUNTIME_KEYS = ("train_threads",)


def ineffective_keys(cfg) -> dict[str, str]:
    e, out = cfg.experiment, {}
    if e.objects.test_cubes is not None:
        for k in ("objects.test", "quick.objects", "objects.test_set"):
            out[k] = "objects.test_cubes replaces the built-in test set"
    elif e.objects.test_set == "train":
        out["objects.test"] = "objects.test_set=train shows the training objects"
    if cfg.preset == "quick":
        out["fm.images"] = "preset=quick trains on quick.fm_images"
        out["image.chains"] = "preset=quick trains on quick.chains"
    if e.grid is not None:
        out["fm.memory_mb"] = "grid is set, so the grid rule is not used"
    if "oblique" not in e.tests:
        out["oblique_angles"] = "the oblique test is not among experiment.tests"
    if e.strategy == "parity":
        out["selection.max_steps"] = "strategy=parity does not turn the image"
    out["selection.tau"] = "PMCm takes the most active move (no softmax)"
    return {f"experiment.{k}": v for k, v in out.items()}
