"""The schema of Experiment 5 (``conf/experiment/exp5.yaml``): :class:`Exp5Config`, its groups
(``world``, ``acquisition``, ``brain``, ``sequencing``, ``engine``, ``quick``), every value
checked, and the two test situations of the thesis.

The groups the model reads are the model's own parameter dataclasses
(:class:`~neuroimagery.models.tool_use.AcquisitionParams`, :class:`~neuroimagery.models.tool_use.BrainParams`,
:class:`~neuroimagery.models.tool_use.SequencingParams`); the world's and the engine's are here.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from ...core.bounds import Rule, bounded, check_declared
from ...models.tool_use.params import AcquisitionParams, BrainParams, SequencingParams
from ...robot.events import EVENTS
from ...robot.config import TABLE_CONTACTS
from ...core.thesis import EXP5, EXP5_TABLE_7_1

SITUATIONS = {"behind": 1, "far": 4}  # thesis: posture 1 = tool behind toy, posture 4 = tool far from toy
THESIS = EXP5  # the thesis's HP1 / HP2 numbers (neuroimagery.core.thesis, "Experiment 5")
THESIS_TABLE_7_1 = EXP5_TABLE_7_1
# settings that change no result (how the work is spread, where libraries come from)
ENGINE_KEYS = ("engine.n_jobs", "engine.reuse_libraries")
# settings that may differ between pooled runs besides the seed: how the work was spread, and how
# many robots (neuroimagery.app.pool)
POOL_FREE_KEYS = ENGINE_KEYS + ("engine.filmstrip_repetition", "repetitions", "quick.repetitions")
POOL_ROWS = "individuals.csv"  # the pooled rows (neuroimagery.app.pool, with POOL_FREE_KEYS and pool_runs)


@dataclass
class WorldParams:
    """The world the robots live in and how it moves them (``experiment.world``): the arguments
    of the environment (``robot.environment.ToolWorldEnvironment``)."""

    environment: str = "robot"  # 'robot' (pybullet ToolWorld) or 'module:Class' of another Environment
    duration_s: float = bounded(1.5, gt=0)  # duration of one primitive (DMP time constant, eq. 7.2-7.5)
    explore_weight_sigma: float = bounded(300.0, gt=0)  # std of a random DMP's shape weights (goals: docs/robot.md)
    search_goal_sigma: float = bounded(0.05, gt=0)  # rad, PI^BB exploration std of the goals (eq. 7.6)
    search_weight_sigma: float = bounded(30.0, gt=0)  # PI^BB exploration std of the shape weights (eq. 7.6)
    # m; no rake point travels farther in one physics step (robot.config.WorldConfig, docs/robot.md,
    # physics step criterion); null: two fixed 10 ms steps per control step
    max_substep_travel: Optional[float] = bounded(0.008, gt=0)
    # how the table meets the rake (robot.config.WorldConfig, docs/robot.md "The table, the grip and
    # the arm"): 'lift' = the pose lifted vertically where the command would sink it | 'grip' = the
    # rake turns in the hand by at most grip_pivot_max (rad), beyond that the table stops the arm
    table_contact: str = bounded("lift", choices=TABLE_CONTACTS)
    grip_pivot_max: float = bounded(math.radians(10.0), ge=0, lt=math.pi / 2)

    RULES = (Rule("environment", lambda w: w.environment == "robot" or ":" in w.environment,
                  "must be 'robot' or 'module:Class'"),)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.world.")

    def env_kwargs(self) -> dict:
        """The keyword arguments of ``ToolWorldEnvironment`` (all but ``environment`` and the
        physics settings of ``world_config``)."""
        skip = ("environment", "max_substep_travel", "table_contact", "grip_pivot_max")
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in skip}

    def world_config(self):
        """The pybullet world's ``WorldConfig`` with this group's physics settings."""
        from ...robot.config import WorldConfig

        return WorldConfig(max_substep_travel=self.max_substep_travel, table_contact=self.table_contact,
                           grip_pivot_max=self.grip_pivot_max)


@dataclass
class EngineParams:
    """How the work is organised (``experiment.engine``)."""

    n_jobs: int = bounded(2, ge=1)  # parallel tasks (joblib processes); 1 runs in this process
    filmstrip_repetition: int = bounded(0, ge=0)  # repetition whose planning test is filmed (imagined vs real)
    # a run directory whose skill libraries are reused when every setting of skill acquisition
    # (Fig. 7.5: the world and acquisition groups, brain.c2_eta, the seed) matches; only action sequencing (Fig. 7.6) is then run again, e.g. in a sweep over
    # brain.eta or sequencing.temperature. '' = none. Libraries of this run's own directory are
    # always reused that way.
    reuse_libraries: str = ""

    RULES = (Rule("reuse_libraries", lambda e: not e.reuse_libraries or (Path(e.reuse_libraries) / "checkpoints").is_dir(),
                  "must be a run directory with a checkpoints/ folder"),)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.engine.")


@dataclass
class QuickParams:
    """What ``preset=quick`` shrinks (``experiment.quick``)."""

    repetitions: int = bounded(3, ge=1)  # repetitions per group and situation (a first look in a few minutes)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.quick.")


GROUPS = {"world": WorldParams, "acquisition": AcquisitionParams, "brain": BrainParams,
          "sequencing": SequencingParams, "engine": EngineParams}


@dataclass
class Exp5Config:
    """Schema of ``conf/experiment/exp5.yaml``: the protocol (section 7.1.3) at the top, the
    settings of each part of the model and of the run in their groups; every value is checked
    when the groups are built."""

    name: str = "exp5"
    # --- simulations (section 7.1.3)
    repetitions: int = bounded(30, ge=1)  # repetitions per group and situation (thesis: 30)
    hp1_levels: list[int] = bounded(factory=lambda: [2, 3, 4, 5, 6], le=len(EVENTS), each=True, nonempty=True)  # IM detectors per HP1 group
    hp1_ages: list[int] = bounded(factory=lambda: [14, 16, 18, 20, 22], ge=0, each=True)  # months, one per HP1 level
    hp1_training_trials: int = bounded(10, ge=0)  # training trials of every HP1 robot
    hp2_trials: list[int] = bounded(factory=lambda: [0, 2, 4, 6, 8, 10], ge=0, each=True, nonempty=True)  # training trials per HP2 group
    hp2_ages: list[int] = bounded(factory=lambda: [14, 14, 16, 18, 20, 22], ge=0, each=True)  # months, one per HP2 level
    base_detectors: list[str] = bounded(factory=lambda: ["retrieve", "touch"], choices=EVENTS, each=True)  # always on under HP1
    situations: list[str] = bounded(factory=lambda: ["behind", "far"], choices=tuple(SITUATIONS), each=True, nonempty=True)  # tool behind / far from toy
    quick: QuickParams = field(default_factory=QuickParams)  # what preset=quick shrinks
    world: WorldParams = field(default_factory=WorldParams)  # the environment and its movements
    acquisition: AcquisitionParams = field(default_factory=AcquisitionParams)  # skill acquisition (Fig. 7.5)
    brain: BrainParams = field(default_factory=BrainParams)  # C1-C4 rates and read-outs (Fig. 7.4, eq. 7.1)
    sequencing: SequencingParams = field(default_factory=SequencingParams)  # action sequencing (Fig. 7.6)
    engine: EngineParams = field(default_factory=EngineParams)  # parallel tasks, reuse, filming

    RULES = (
        Rule("name", lambda c: c.name == "exp5", "must be 'exp5'"),
        Rule("hp1_ages", lambda c: len(c.hp1_ages) == len(c.hp1_levels), "must give one age per entry of hp1_levels"),
        Rule("hp2_ages", lambda c: len(c.hp2_ages) == len(c.hp2_trials), "must give one age per entry of hp2_trials"),
        Rule("base_detectors", lambda c: len(set(c.base_detectors)) == len(c.base_detectors),
             f"must be distinct events of {EVENTS}"),
        Rule("hp1_levels", lambda c: all(len(c.base_detectors) <= k for k in c.hp1_levels),
             "must each be at least the number of base_detectors"),
        Rule("situations", lambda c: len(set(c.situations)) == len(c.situations), "must be distinct"),
    )

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)


def from_dict(d: dict) -> Exp5Config:
    """An :class:`Exp5Config` from its ``asdict`` form (the groups as dicts)."""
    kinds = {"quick": QuickParams, **GROUPS}
    return Exp5Config(**{k: kinds[k](**v) if k in kinds else v for k, v in d.items()})


def dotted(config: dict) -> dict:
    """The settings of a configuration in its ``asdict`` form under dotted keys (``brain.c3_eta``)."""
    out = {}
    for k, v in config.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in dotted(v).items()})
        else:
            out[k] = v
    return out


CONFIG = Exp5Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ()  # the robot's eye is part of the world (neuroimagery.robot), not the vision group
CHECKPOINTS = ("exp5_index",)
RUNTIME_KEYS = ("engine.n_jobs", "engine.reuse_libraries", "engine.filmstrip_repetition")  # speed, reuse, who is filmed
TEST_KEYS = ()


def ineffective_keys(cfg) -> dict[str, str]:
    out = {"participants": "exp5 simulates experiment.repetitions robots per group and situation"}
    if cfg.preset == "quick":
        out["experiment.repetitions"] = "preset=quick runs experiment.quick.repetitions"
    return out
