"""The schema of Experiment 5 (``conf/experiment/exp5.yaml``): :class:`Exp5Config`, every value
checked, and the two test situations of the thesis."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..models.tool_use import CHOICES, EVENTS
from ..thesis import EXP5, EXP5_TABLE_7_1

SITUATIONS = {"behind": 1, "far": 4}  # thesis: posture 1 = tool behind toy, posture 4 = tool far from toy
THESIS = EXP5  # the thesis's HP1 / HP2 numbers (neuroimagery.thesis, "Experiment 5")
THESIS_TABLE_7_1 = EXP5_TABLE_7_1

@dataclass
class Exp5Config:
    """Schema of ``conf/experiment/exp5.yaml``; every value is checked in ``__post_init__``."""

    name: str = "exp5"
    # --- simulations (section 7.1.3)
    repetitions: int = 30  # repetitions per group and situation (thesis: 30)
    quick_repetitions: int = 3  # repetitions with preset=quick (a first look in a few minutes)
    hp1_levels: list[int] = field(default_factory=lambda: [2, 3, 4, 5, 6])  # IM detectors per HP1 group
    hp1_ages: list[int] = field(default_factory=lambda: [14, 16, 18, 20, 22])  # months, one per HP1 level
    hp1_training_trials: int = 10  # training trials of every HP1 robot
    hp2_trials: list[int] = field(default_factory=lambda: [0, 2, 4, 6, 8, 10])  # training trials per HP2 group
    hp2_ages: list[int] = field(default_factory=lambda: [14, 14, 16, 18, 20, 22])  # months, one per HP2 level
    base_detectors: list[str] = field(default_factory=lambda: ["retrieve", "touch"])  # always on under HP1
    situations: list[str] = field(default_factory=lambda: ["behind", "far"])  # tool behind / far from toy
    # --- action sequencing (Fig. 7.6, eq. 7.1)
    attempts: int = 5  # primitives per trial (thesis: 5)
    q_form: str = "standard"  # eq. 7.1 sign: 'standard' r + gamma maxQ (default) | 'printed' r - gamma maxQ
    eta: float = 1e-4  # C4 Q-learning rate (thesis: 0.0001) on the 2 x 240 x 320 binary PC map
    gamma: float = 0.8  # discount (thesis: 0.8)
    temperature: float = 0.1  # softmax temperature of action selection in training trials (not given)
    test_temperature: float = 0.1  # softmax temperature in the test trial (not given)
    # how a planning child is tested (Fig. 7.6 does not say): 'act' = each attempt chooses from the
    # real scene with the C4 learnt in mind, imagines, performs and looks again | 'plan' = the whole
    # plan is made in mind from the initial image, then performed. See docs/exp5.md.
    planning_test: str = "act"
    # Fig. 7.6 "select one active neuron of PMC": a unit is active when its PMC activity (C1 + C4)
    # is above this; 0 = above the maps' resting level (the default, docs/exp5.md). A child with
    # no active unit does not move.
    active_threshold: float = 0.0
    # --- skill acquisition (Fig. 7.5, eq. 7.6-7.8)
    n_dmps: int = 10  # M1 / PMC units (thesis: 10)
    pibb_samples: int = 10  # K samples per posture and update (thesis: 10)
    pibb_temperature: float = 0.1  # tau of eq. 7.7 on the 0/1 costs (not given)
    pibb_decay: float = 0.9  # exploration covariance factor per PI^BB update (not given)
    # a PI^BB update whose K samples all cost the same (none or all achieved the event from that
    # posture): 'average' = the plain mean of the samples, eq. 7.8 with uniform weights (a random
    # step) | 'keep' = no information, mean and covariance unchanged. See docs/exp5.md.
    pibb_flat: str = "average"
    max_epochs: int = 10  # PI^BB epochs at most (thesis: 10)
    competence_tolerance: float = 0.05  # stop when the competence changes by less (thesis: 0.05)
    c1_repeats: int = 10  # C1 updates per PI^BB update (thesis: 10)
    c2_repeats: int = 10  # C2 updates per successful competence check (thesis: 10)
    c3_repeats: int = 50  # C3 updates per successful competence check (thesis: 50)
    c1_eta: float = 0.1  # C1 Hebbian rate (not given)
    c2_eta: float = 0.1  # C2 Hebbian rate (not given)
    c3_eta: float = 0.1  # C3 SOM rate (not given); 50 steps make the prototype the last outcome
    c3_sigma: float = 0.1  # C3 neighbourhood width in units; small: each pair keeps its own unit
    c3_action_gain: float = 100.0  # weight of the primitive's code against the image in C3's match ('joint')
    # how C3 finds the unit that imagines "primitive a in this image": 'practised' = recognise the
    # nearest of the initial situations practised in (Fig. 7.5 B), then that situation's unit for a
    # (never trained: no change imagined) | 'situation' = the same among the situations stored in C3
    # only | 'joint' = nearest [image, gain * code] (any situation where a once succeeded answers)
    c3_recall: str = "practised"
    hip_threshold: float = 0.5  # a distal goal (C2 -> HIP) this active makes an event "not new"
    explore_batch: int = 8  # exploration movements rolled out per batch (the first new event wins)
    explore_max_rollouts: int = 400  # give up looking for further events after this many movements
    explore_patience: int = 40  # rollouts of one DMP without a new event before it is drawn afresh
    # --- movements (DMP eq. 7.2-7.5 on the pybullet world)
    duration_s: float = 1.5  # duration of one primitive (DMP time constant)
    explore_weight_sigma: float = 300.0  # std of a random DMP's shape weights (goals: docs/robot.md)
    search_goal_sigma: float = 0.05  # rad, PI^BB exploration std of the goals
    search_weight_sigma: float = 30.0  # PI^BB exploration std of the shape weights
    # the DMPs left free once every enabled event has its skill (n_dmps = 10 for 6 events):
    # 'none' = unused | 'unmastered' = exploration goes on and an event firing from a situation
    # where it is not yet mastered (distal goal off) is learnt again by a spare DMP. docs/exp5.md.
    spare_dmps: str = "none"
    # what C3 (the mental images) holds: 'success' = a primitive's outcome from an initial situation
    # only where it achieved its event (Fig. 7.5) | 'every' = also its outcome from the other initial
    # situations (the learnt movement performed there). Acts in the brain only. docs/exp5.md.
    c3_outcomes: str = "success"
    # whether a scene between moves keeps the toy's turn about the vertical: 'keep' = as the last
    # move left it | 'reset' = square again (its place is kept either way). See docs/exp5.md.
    toy_turn: str = "keep"
    # --- engine
    environment: str = "robot"  # 'robot' (pybullet ToolWorld) or 'module:Class' of another Environment
    share_library_across_situations: bool = False  # one library per repetition for both situations
    n_jobs: int = 2  # parallel tasks (joblib processes); 1 runs in this process
    filmstrip_repetition: int = 0  # repetition whose planning test is filmed (imagined vs real)
    # a run directory whose skill libraries are reused when every setting of skill acquisition
    # (Fig. 7.5: the world, acquisition and C2 keys, the seed) matches; only action sequencing
    # (Fig. 7.6) is then run again, e.g. in a sweep over eta or temperature. '' = none. Libraries
    # of this run's own directory are always reused that way.
    reuse_libraries: str = ""

    def __post_init__(self) -> None:
        def bad(key, why):
            raise ValueError(f"experiment.{key} {why}, got {getattr(self, key)!r}")

        if self.name != "exp5":
            bad("name", "must be 'exp5'")
        for key in ("repetitions", "quick_repetitions", "attempts", "n_dmps", "pibb_samples", "max_epochs",
                    "explore_batch", "explore_max_rollouts", "explore_patience", "n_jobs"):
            if int(getattr(self, key)) < 1:
                bad(key, "must be >= 1")
        for key in ("hp1_training_trials", "c1_repeats", "c2_repeats", "c3_repeats", "filmstrip_repetition"):
            if int(getattr(self, key)) < 0:
                bad(key, "must be >= 0")
        if self.pibb_samples < 2:
            bad("pibb_samples", "must be >= 2")
        if self.n_dmps < len(EVENTS):
            bad("n_dmps", f"must be >= {len(EVENTS)} (one primitive per event)")
        if self.q_form not in ("standard", "printed"):
            bad("q_form", "must be 'standard' or 'printed'")
        for key in ("eta", "c1_eta", "c2_eta", "c3_eta"):
            if not 0 < getattr(self, key) <= 1:
                bad(key, "must be in (0, 1]")
        if not 0 <= self.gamma <= 1:
            bad("gamma", "must be in [0, 1]")
        if not 0 < self.pibb_decay <= 1:
            bad("pibb_decay", "must be in (0, 1]")
        if not 0 <= self.competence_tolerance <= 1:
            bad("competence_tolerance", "must be in [0, 1]")
        if not 0 <= self.active_threshold < 1:
            bad("active_threshold", "must be in [0, 1)")
        if not 0 <= self.hip_threshold <= 1:
            bad("hip_threshold", "must be in [0, 1]")
        for key in ("temperature", "test_temperature", "pibb_temperature", "c3_sigma", "c3_action_gain",
                    "duration_s", "explore_weight_sigma", "search_goal_sigma",
                    "search_weight_sigma"):
            if not getattr(self, key) > 0:
                bad(key, "must be > 0")
        if len(self.hp1_levels) != len(self.hp1_ages) or not self.hp1_levels:
            bad("hp1_ages", "must give one age per entry of hp1_levels")
        if len(self.hp2_trials) != len(self.hp2_ages) or not self.hp2_trials:
            bad("hp2_ages", "must give one age per entry of hp2_trials")
        if any(t < 0 for t in self.hp2_trials):
            bad("hp2_trials", "must be >= 0")
        if any(e not in EVENTS for e in self.base_detectors) or len(set(self.base_detectors)) != len(self.base_detectors):
            bad("base_detectors", f"must be distinct events of {EVENTS}")
        if any(not len(self.base_detectors) <= k <= len(EVENTS) for k in self.hp1_levels):
            bad("hp1_levels", f"must lie in [{len(self.base_detectors)}, {len(EVENTS)}]")
        if not self.situations or any(s not in SITUATIONS for s in self.situations) or len(set(self.situations)) != len(self.situations):
            bad("situations", f"must be distinct names of {sorted(SITUATIONS)}")
        for key, allowed in CHOICES.items():
            if getattr(self, key) not in allowed:
                bad(key, f"must be one of {', '.join(map(repr, allowed))}")
        if self.environment != "robot" and ":" not in self.environment:
            bad("environment", "must be 'robot' or 'module:Class'")
        if self.reuse_libraries and not (Path(self.reuse_libraries) / "checkpoints").is_dir():
            bad("reuse_libraries", "must be a run directory with a checkpoints/ folder")
