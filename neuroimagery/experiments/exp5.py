"""Experiment 5: tool-use development in infant robots (thesis ch. 7, Fig. 7.5-7.6, 7.9-7.10).

Two simulations, each group 30 repetitions x 2 situations (tool behind toy = posture 1, tool far
from toy = posture 4), every individual tested both as a reactive and as a planning child:

* HP1: 2, 3, 4, 5, 6 IM detectors (ages 14-22 months; retrieve and touch always on, the others
  drawn at random per individual), 10 training trials.
* HP2: all six detectors, 0, 2, 4, 6, 8, 10 training trials (ages 14, 14, 16, 18, 20, 22 months).

Work unit ("task"): one repetition and one situation (or both, with
``share_library_across_situations``). The task acquires one skill library with all six
detectors (Fig. 7.5); every individual of that task keeps the skills of its own enabled
detectors, its C1/C2/C3 training is replayed for exactly those skills, and it then runs Fig. 7.6.
All individuals of a task share the (deterministic) outcomes of skill sequences, so the physics
of a given sequence runs once. Tasks run in parallel (joblib) and each leaves one small result
file in ``checkpoints/`` so an interrupted run resumes where it stopped (rerun with the same
``hydra.run.dir``).

``cfg.participants`` is not used: the individuals are ``repetitions x situations`` per group.
``train`` runs the whole developmental simulation (acquisition, training trials and the test of
every individual, since each individual's training is its own); ``evaluate`` aggregates, draws
and reports.
"""
from __future__ import annotations

import importlib
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from ..errors import UserInputError
from ..models.tool_use import (CHOICES, EVENTS, N_POSTURES, AcquisitionConfig, Library, Outcomes, ToolUseBrain, acquire_skills,
                               build_brain, sequence_trial)
from ..nn.seeding import participant_seed
from ..robot.config import POSTURE_4, WorldConfig
from . import exp5_tasks as task_files

SITUATIONS = {"behind": 1, "far": 4}  # thesis: posture 1 = tool behind toy, posture 4 = tool far from toy
THESIS = {  # read off Fig. 7.9-7.10 and the text of section 7.1.3 (approximate)
    "hp1": {"behind": {2: 1.0, 3: 0.9, 4: 0.9, 5: 0.9, 6: 0.9}, "far": {2: 0.0, 3: 0.1, 4: 0.4, 5: 0.45, 6: 0.6}},
    "hp2": {"behind": {0: 0.6}, "far": {0: 0.2}},
}
THESIS_TABLE_7_1 = {
    "posture-1": {"events": [1, 0, 1, 0, 1, 0], "skills": [1, 0, 1, 0, 1, 0]},
    "posture-2": {"events": [0, 1, 1, 0, 1, 0], "skills": [1, 1, 1, 0, 1, 0]},
    "posture-3": {"events": [0, 1, 1, 1, 1, 1], "skills": [0, 1, 1, 1, 1, 1]},
    "posture-4": {"events": [0, 1, 1, 1, 1, 1], "skills": [0, 1, 1, 1, 1, 1]},
}


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
    # Fig. 7.6 "select one active neuron of PMC": only units whose PMC activity (C1 + C4) exceeds
    # this are candidates for the softmax, and a child with none does not move. 0.1 is C1's
    # smallest teaching signal (one success in ten PI^BB samples, Fig. 7.5 B) | 0 = every acquired
    # unit is a candidate (the version before this key). See docs/exp5.md.
    active_threshold: float = 0.1
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
    # --- movements (DMP eq. 7.2-7.5 on the pybullet world)
    duration_s: float = 1.5  # duration of one primitive (DMP time constant)
    explore_goal_sigma: float = 0.35  # rad, goal noise of an exploratory movement
    explore_weight_sigma: float = 300.0  # shape-weight noise of an exploratory movement
    search_goal_sigma: float = 0.05  # rad, PI^BB exploration std of the goals
    search_weight_sigma: float = 30.0  # PI^BB exploration std of the shape weights
    # what a primitive's 7 goal numbers are: 'relative' = joint displacement from the start (the
    # same movement shape from every situation, so its effect depends on where the rake starts) |
    # 'absolute' = joint angles (every start ends in the same arm posture). See docs/exp5.md.
    goal_frame: str = "absolute"
    # the reach of one movement (WorldConfig.max_goal_offset_rad = 0.15 rad): 'goal' = only the DMP
    # goal is bounded, as in the world (the shape term can carry a joint 2-4 times farther on the
    # way) | 'path' = every joint stays within the bound of its start at every step. See docs/exp5.md.
    reach_bound: str = "goal"
    # which joint vector is posture 4, the tool-far situation (WorldConfig.posture_4): 'right' =
    # rake head at (0.60, -0.38), 17 cm from the toy | 'far' = (0.525, -0.43), 22.5 cm.
    # See docs/robot.md and docs/exp5.md.
    posture_4: str = "right"
    # m, the reachable area: the retrieve event fires when the toy's centre comes nearer to the robot
    # than this (WorldConfig.retrieve_x; the toy starts at x = 0.56). See docs/robot.md and docs/exp5.md.
    retrieve_x: float = 0.48
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
                    "explore_batch", "explore_max_rollouts", "n_jobs"):
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
                    "duration_s", "explore_goal_sigma", "explore_weight_sigma", "search_goal_sigma",
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
        if self.posture_4 not in POSTURE_4:
            bad("posture_4", f"must be one of {sorted(POSTURE_4)}")
        toy_x = WorldConfig().toy_xy[0]
        if not 0.3 <= self.retrieve_x < toy_x:
            bad("retrieve_x", f"must lie in [0.3, {toy_x}) m (the toy starts at x = {toy_x})")
        if self.environment != "robot" and ":" not in self.environment:
            bad("environment", "must be 'robot' or 'module:Class'")
        if self.reuse_libraries and not (Path(self.reuse_libraries) / "checkpoints").is_dir():
            bad("reuse_libraries", "must be a run directory with a checkpoints/ folder")


CONFIG = Exp5Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.manifest)
INPUTS = ()  # the robot's eye is part of the world (neuroimagery.robot), not the vision group
CHECKPOINTS = ("exp5_index",)
RUNTIME_KEYS = ("n_jobs", "reuse_libraries", "filmstrip_repetition")  # speed, reuse and which robot is filmed
TEST_KEYS = ()


def ineffective_keys(cfg) -> dict[str, str]:
    out = {"participants": "exp5 simulates experiment.repetitions robots per group and situation"}
    if cfg.preset == "quick":
        out["experiment.repetitions"] = "preset=quick runs experiment.quick_repetitions"
    return out


STRATEGIES = ("reactive", "planning")


# ---------------------------------------------------------------------------------- helpers
def _exp(cfg) -> Exp5Config:
    return cfg.experiment


def repetitions(cfg) -> int:
    e = _exp(cfg)
    return e.quick_repetitions if cfg.preset == "quick" else e.repetitions


def trained_count(cfg) -> tuple[int, str]:
    """How many robots a run simulates (``cfg.participants`` is not used): repetitions x situations
    x groups, each tested as a reactive and as a planning child."""
    e = _exp(cfg)
    return repetitions(cfg) * len(e.situations) * len(groups(e)), "robots"


def acquisition_config(e: Exp5Config) -> AcquisitionConfig:
    return AcquisitionConfig(n_dmps=e.n_dmps, pibb_samples=e.pibb_samples, pibb_temperature=e.pibb_temperature,
                             pibb_decay=e.pibb_decay, pibb_flat=e.pibb_flat, max_epochs=e.max_epochs,
                             competence_tolerance=e.competence_tolerance, c1_repeats=e.c1_repeats,
                             c2_repeats=e.c2_repeats, c3_repeats=e.c3_repeats, hip_threshold=e.hip_threshold,
                             explore_batch=e.explore_batch, explore_max_rollouts=e.explore_max_rollouts,
                             spare_dmps=e.spare_dmps, c3_outcomes=e.c3_outcomes)


_ENV_KEYS = ("environment", "duration_s", "explore_goal_sigma", "explore_weight_sigma", "search_goal_sigma",
             "search_weight_sigma", "goal_frame", "reach_bound", "posture_4", "retrieve_x", "toy_turn")
# the settings a task's skill library depends on (Fig. 7.5); the other keys act only in Fig. 7.6
_LIBRARY_KEYS = _ENV_KEYS + ("n_dmps", "pibb_samples", "pibb_temperature", "pibb_decay", "pibb_flat", "max_epochs",
                             "competence_tolerance", "c1_repeats", "c2_repeats", "c3_repeats", "hip_threshold",
                             "explore_batch", "explore_max_rollouts", "spare_dmps", "c2_eta",
                             "share_library_across_situations")
# settings that change no result (how the work is spread, where libraries come from)
_ENGINE_KEYS = ("n_jobs", "reuse_libraries")
_WORKER_ENV: dict[tuple, object] = {}  # one world per worker process, reused by its tasks


def _task_environment(e: Exp5Config):
    """This process's world for ``e`` (built once: loading the robot takes seconds), emptied of
    the previous task's image cache and timings so each task's numbers are its own."""
    key = tuple(getattr(e, k) for k in _ENV_KEYS)
    env = _WORKER_ENV.get(key)
    if env is None:
        for old in _WORKER_ENV.values():
            if hasattr(old, "close"):
                old.close()
        _WORKER_ENV.clear()
        env = _WORKER_ENV[key] = make_environment(e)
    if hasattr(env, "_images"):
        env._images.clear()
    if hasattr(env, "timing"):
        env.timing = {k: type(v)(0) for k, v in env.timing.items()}
    return env


def make_environment(e: Exp5Config):
    """The world the robots live in: the pybullet ToolWorld, or ``module:Class`` (tests' stand-ins)."""
    if e.environment == "robot":
        from ..models.tool_use import ToolWorldEnvironment

        return ToolWorldEnvironment(WorldConfig(posture_4=e.posture_4, retrieve_x=e.retrieve_x), duration_s=e.duration_s, explore_goal_sigma=e.explore_goal_sigma,
                                    explore_weight_sigma=e.explore_weight_sigma,
                                    search_goal_sigma=e.search_goal_sigma, search_weight_sigma=e.search_weight_sigma,
                                    goal_frame=e.goal_frame, reach_bound=e.reach_bound, toy_turn=e.toy_turn)
    mod, _, cls = e.environment.partition(":")
    try:
        return getattr(importlib.import_module(mod), cls)()
    except (ImportError, AttributeError) as err:
        raise UserInputError(f"experiment.environment: cannot load {e.environment!r} ({err})") from None


def groups(e: Exp5Config) -> list[dict]:
    """Every group: hypothesis, level, age, training trials and number of detectors."""
    out = [dict(hypothesis="hp1", level=k, age_months=a, trials=e.hp1_training_trials, detectors=k)
           for k, a in zip(e.hp1_levels, e.hp1_ages)]
    out += [dict(hypothesis="hp2", level=t, age_months=a, trials=t, detectors=len(EVENTS))
            for t, a in zip(e.hp2_trials, e.hp2_ages)]
    return out


def tasks(cfg) -> list[dict]:
    e = _exp(cfg)
    sits = list(e.situations)
    out = []
    for r in range(repetitions(cfg)):
        if e.share_library_across_situations:
            out.append(dict(repetition=r, situations=sits, key=f"rep{r:03d}"))
        else:
            out += [dict(repetition=r, situations=[s], key=f"rep{r:03d}_{s}") for s in sits]
    return out


def _gen(seed: int, *ids: int) -> torch.Generator:
    key = 0
    for i in ids:
        key = key * 1009 + int(i) + 1
    g = torch.Generator()
    g.manual_seed(participant_seed(seed, key % (2**31)))
    return g


def detectors_for(e: Exp5Config, n: int, g: torch.Generator) -> list[str]:
    """The ``n`` enabled IM detectors: the base ones plus a random draw of the rest."""
    rest = [x for x in EVENTS if x not in e.base_detectors]
    extra = [rest[i] for i in torch.randperm(len(rest), generator=g)[: n - len(e.base_detectors)].tolist()]
    return [x for x in EVENTS if x in e.base_detectors or x in extra]


def _pack(img: torch.Tensor) -> torch.Tensor:
    return (img.clamp(0, 1) * 255).round().to(torch.uint8)


def _small_maps(maps: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Weight maps at half resolution in float16, small enough to keep in the filmed task's checkpoint."""
    return {k: torch.nn.functional.avg_pool2d(v[None, None].float(), 2)[0, 0].half() for k, v in maps.items()}


def routes_available(outcomes: Outcomes, posture: int, names: Sequence[str]) -> tuple[int, int]:
    """What the world offers a robot with primitives ``names`` from ``posture``, whatever it learns:
    the number of single primitives that retrieve the toy, and of ordered pairs (a, b) where a alone
    does not and a then b does (individuals.csv ``routes_1``, ``routes_2``; rollouts are cached in
    ``outcomes`` and shared with the action sequencing)."""
    one = {a for a in names if outcomes.after(posture, (a,)).retrieved}
    two = sum(outcomes.after(posture, (a, b)).retrieved for a in names if a not in one for b in names)
    return len(one), int(two)


def imagined_routes(brain: ToolUseBrain, outcomes: Outcomes, posture: int, skills: Sequence) -> tuple[int, int, int]:
    """What a planning child's mental images offer from ``posture``: the number of primitives that
    C3, run backwards, imagines to bring the toy into reach, of ordered pairs a, b (a alone not
    imagined to) whose second mental image shows it in reach, and of these imagined routes how many
    also bring the toy in for real (individuals.csv ``imagined_1``, ``imagined_2``,
    ``imagined_true``; the real check reuses the rollouts of :func:`routes_available`)."""
    env = outcomes.env
    x0 = outcomes.image(posture, ())
    first = {s.name: brain.imagine(x0, s.unit) for s in skills}
    one = [a for a, im in first.items() if env.reward(im) > 0]
    two = [(a, s.name) for a, im in first.items() if a not in one for s in skills
           if env.reward(brain.imagine(im, s.unit)) > 0]

    def real(moves):
        return outcomes.after(posture, moves[:1]).retrieved or outcomes.after(posture, moves).retrieved

    true = sum(real((a,)) for a in one) + sum(real(ab) for ab in two)
    return len(one), len(two), int(true)


# ---------------------------------------------------------------------------------- one task
def run_task(e: Exp5Config, seed: int, task: dict, path: str | None = None, library: dict | None = None) -> dict:
    """Acquire one library (or take ``library``, a stored one acquired with the same settings),
    then simulate every individual built on it (all groups, strategies)."""
    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()
    env = _task_environment(e)
    acq = acquisition_config(e)
    r = task["repetition"]
    sit_ids = [list(SITUATIONS).index(s) for s in task["situations"]]
    g_lib = _gen(seed, 1, r, *sit_ids)
    brain_kw = dict(n_dmps=e.n_dmps, c1_eta=e.c1_eta, c2_eta=e.c2_eta, c3_eta=e.c3_eta, c3_sigma=e.c3_sigma,
                    c3_action_gain=e.c3_action_gain, q_eta=e.eta, q_gamma=e.gamma, q_form=e.q_form,
                    c3_recall=e.c3_recall)
    if library is not None:
        lib = Library.from_state(library)
    else:
        lib_brain = ToolUseBrain(env.image_shape, seed=seed, **brain_kw)
        lib = acquire_skills(env, EVENTS, acq, g_lib, brain=lib_brain)
    t_acq = time.perf_counter() - t0
    rows, film = [], None
    built: dict[tuple, ToolUseBrain] = {}
    # per (situation, detectors): routes_1, routes_2 (the world) and imagined_1, imagined_2,
    # imagined_true (the mental images; C3 does not change in action sequencing)
    routes: dict[tuple, dict[str, int]] = {}
    for sit in task["situations"]:
        posture = SITUATIONS[sit]
        outcomes = Outcomes(env, {s.name: s for s in lib.skills}, env.perceive)
        for gi, grp in enumerate(groups(e)):
            g_ind = _gen(seed, 2, r, list(SITUATIONS).index(sit), gi)
            enabled = detectors_for(e, grp["detectors"], g_ind)
            sub = lib.subset(enabled)
            key = tuple(enabled)
            if key not in built:
                built[key] = build_brain(env, sub, acq, ToolUseBrain(env.image_shape, seed=seed, **brain_kw),
                                         _gen(seed, 3, r), env.perceive, outcomes=outcomes)
            if (sit, key) not in routes:
                r1, r2 = routes_available(outcomes, posture, [s.name for s in sub.skills])
                i1, i2, i_true = imagined_routes(built[key], outcomes, posture, sub.skills)
                routes[(sit, key)] = dict(routes_1=r1, routes_2=r2, imagined_1=i1, imagined_2=i2, imagined_true=i_true)
            for strategy in STRATEGIES:
                # only C4 learns in Fig. 7.6: every individual starts from the built brain with a fresh C4
                brain = built[key]
                brain.reset_c4()
                train_ok = []
                for _ in range(grp["trials"]):
                    rec = sequence_trial(brain, outcomes, sub.skills, posture, strategy, True, e.attempts,
                                         e.temperature, g_ind, planning_test=e.planning_test,
                                         active_threshold=e.active_threshold)
                    train_ok.append(rec.success if strategy == "reactive" else rec.imagined_success)
                filming = (film is None and r == e.filmstrip_repetition and strategy == "planning")
                test = sequence_trial(brain, outcomes, sub.skills, posture, strategy, False, e.attempts,
                                      e.test_temperature, g_ind, record_frames=filming,
                                      planning_test=e.planning_test, active_threshold=e.active_threshold)
                if filming and test.success and (sit == "far" or gi == len(groups(e)) - 1):
                    film = dict(situation=sit, hypothesis=grp["hypothesis"], level=grp["level"],
                                strategy=strategy, start=_pack(outcomes.image(posture, ())),
                                frames=[dict(action=f["action"], reward=f["reward"], real=_pack(f["real"]),
                                             imagined=_pack(f["imagined"])) for f in test.frames],
                                maps=_small_maps(brain.maps({s.name: s.unit for s in sub.skills})))
                rows.append(dict(
                    hypothesis=grp["hypothesis"], level=grp["level"], age_months=grp["age_months"],
                    situation=sit, strategy=strategy, repetition=r, library=task["key"],
                    training_trials=grp["trials"], n_detectors=len(enabled), detectors="+".join(enabled),
                    n_skills=len(sub.skills), skills="+".join(s.name for s in sub.skills),
                    train_success_rate=float(np.mean(train_ok)) if train_ok else float("nan"),
                    success=int(test.success), imagined_success=int(test.imagined_success),
                    test_actions=">".join(test.actions), test_attempts=len(test.actions), **routes[(sit, key)]))
    timing = dict(task_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0, acquisition_s=t_acq,
                  explore_rollouts=0 if library is not None else lib.explore_rollouts,
                  learn_rollouts=0 if library is not None else lib.learn_rollouts, library_reused=library is not None)
    timing.update({k: v for k, v in getattr(env, "timing", {}).items()})
    out = dict(task=task, rows=rows, library=lib.to_state(), film=film, timing=timing, config=asdict(e), seed=seed)
    if path is not None:
        task_files.save(out, path)
    return out


# ---------------------------------------------------------------------------------- contract
def _task_path(run_or_dir, key: str) -> Path:
    root = run_or_dir.checkpoints if hasattr(run_or_dir, "checkpoints") else Path(run_or_dir) / "checkpoints"
    return Path(root) / f"exp5_{key}.pt"


def _stored(path: Path) -> dict | None:
    """The task file at ``path`` (None if absent); one that is not plain data or not a task file
    is refused (:func:`exp5_tasks.read_task`)."""
    d = task_files.read_task(path)
    if d is None:
        return None
    # written before these keys existed: their values then
    d["config"] = {"posture_4": "right", "spare_dmps": "none", "retrieve_x": 0.48, "c3_outcomes": "success",
                   "pibb_flat": "average", "toy_turn": "reset", "active_threshold": 0.0,
                   **d["config"]}
    return d


def _same(stored: dict, e: Exp5Config, keys=None) -> bool:
    now = asdict(e)
    keys = [k for k in now if k not in _ENGINE_KEYS] if keys is None else keys
    return all(stored.get(k) == now[k] for k in keys)


def _finished(d: dict | None, e: Exp5Config, seed: int, keys=None) -> bool:
    """Whether the stored task ``d`` was computed with this seed and this configuration (or, with
    ``keys``, these settings of it)."""
    return d is not None and d.get("seed") == seed and _same(d["config"], e, keys)


def _valid(path: Path, e: Exp5Config, seed: int) -> dict | None:
    """The finished task stored at ``path`` if it was computed with this configuration and seed."""
    d = _stored(path)
    return d if _finished(d, e, seed) else None


def _library_of(d: dict | None, e: Exp5Config, seed: int) -> dict | None:
    """The skill library of the stored task ``d`` if it was acquired with this task's acquisition
    settings and seed."""
    return d["library"] if _finished(d, e, seed, _LIBRARY_KEYS) and "library" in d else None


def train(cfg, run) -> dict:
    """Run every task (skipping those already finished in this run directory); return the results."""
    from joblib import Parallel, delayed
    from tqdm.auto import tqdm

    e = _exp(cfg)
    task_files.remove_stale(run.checkpoints)  # left by workers stopped while writing
    todo, done, libraries = [], [], {}
    for t in tasks(cfg):
        d = _stored(_task_path(run, t["key"]))  # each checkpoint is read once
        if _finished(d, e, cfg.seed):
            done.append(d)
            continue
        todo.append(t)
        lib = _library_of(d, e, cfg.seed)
        if lib is None and e.reuse_libraries:
            lib = _library_of(_stored(_task_path(e.reuse_libraries, t["key"])), e, cfg.seed)
        libraries[t["key"]] = lib
    read_back = len(done)
    bar = tqdm(total=len(todo) + len(done), initial=len(done), desc="exp5 tasks", disable=not cfg.progress)
    if todo:
        jobs = (delayed(run_task)(e, cfg.seed, t, str(_task_path(run, t["key"])), libraries[t["key"]]) for t in todo)
        results = Parallel(n_jobs=min(e.n_jobs, len(todo)), return_as="generator_unordered")(jobs)
        try:
            for res in results:
                done.append(res)
                bar.update(1)
                run.logger.scalar("train/task_s", res["timing"]["task_s"], len(done))
        except BaseException:  # an interrupt (SIGINT, SIGTERM) or a failed task: finished tasks stay on disk
            with warnings.catch_warnings():  # joblib's note on the tasks it cancels
                warnings.simplefilter("ignore", UserWarning)
                results.close()  # joblib kills the workers still running (loky: terminate(kill_workers=True))
            task_files.remove_stale(run.checkpoints)
            raise
    bar.close()
    done.sort(key=lambda d: d["task"]["key"])
    run.save_checkpoint("exp5_index", {"keys": [d["task"]["key"] for d in done], "seed": cfg.seed})
    return {"results": done, "read_back": read_back,
            "libraries_reused": sum(v is not None for v in libraries.values())}


def load(cfg, checkpoint_dir) -> dict:
    e = _exp(cfg)
    out = []
    for t in tasks(cfg):
        d = _valid(_task_path(checkpoint_dir, t["key"]), e, cfg.seed)
        if d is None:
            raise UserInputError(f"checkpoint: {checkpoint_dir} has no finished task {t['key']} for this configuration")
        out.append(d)
    return {"results": out, "read_back": len(out)}


def table_7_1(results: list[dict]) -> dict:
    """Which events exploration produced and which skills work, per posture, over all robots."""
    seen = np.zeros((N_POSTURES, len(EVENTS)))
    works = np.zeros((N_POSTURES, len(EVENTS)))
    have = np.zeros(len(EVENTS))
    for d in results:
        lib = Library.from_state(d["library"])
        seen += (np.array(lib.events_seen) > 0)
        for s in lib.skills:
            k = EVENTS.index(s.event)
            have[k] += 1
            works[:, k] += np.array(s.succeeds_from, dtype=float)
    n = max(len(results), 1)
    out = {}
    for p in range(N_POSTURES):
        out[f"posture-{p + 1}"] = {
            "events": [int(v > 0) for v in seen[p]], "skills": [int(v > 0) for v in works[p]],
            "events_share": [round(v / n, 3) for v in seen[p]],
            "skills_share": [round(w / h, 3) if h else 0.0 for w, h in zip(works[p], have)]}
    return out


def _spearman(x, y) -> float | None:
    from scipy.stats import spearmanr

    if len(set(y)) < 2:
        return None
    return float(spearmanr(x, y).statistic)


def group_rates(groups: list[dict]) -> dict[tuple, float]:
    """Success rate of each group of summary.json ``groups``, keyed (hypothesis, level, situation, strategy)."""
    return {(g["hypothesis"], g["level"], g["situation"], g["strategy"]): g["success_rate"] for g in groups}


# Slack of every claim's comparison. Group rates are stored rounded to 4 decimals and are multiples
# of 1 / n (n = 30 robots per run): a claim at its bound (rho exactly 0.8, a rise of exactly 10
# points) must not be decided by rounding. 0.1 point is far less than one robot in 90.
CLAIM_TOL = 1e-3


def thesis_claims(summary: dict, e: Exp5Config) -> list[dict]:
    """The must-show claims of thesis section 7.1.3, each checked on this run's group rates.

    Returns one dict per claim (``claim``, ``value``: the numbers it was judged on, ``holds``);
    claims whose groups were not run are left out. Thresholds: tool behind >= 75 % at every age;
    tool far at the youngest HP1 age <= 15 % ("about 0 %"); tool far before 18 months below every
    tool-behind rate, and >= 10 points higher from 18 months on (Rat-Fischer et al., 2012);
    Spearman's rho of tool far over the HP1 groups >= 0.8; the mean of the trained HP2 groups above
    the untrained group; reactive and planning children within 25 points of each other in every group.
    """
    rate = group_rates(summary["groups"])
    out = []
    tol = CLAIM_TOL

    def claim(what, value, holds):
        out.append(dict(claim=what, value=value, holds=bool(holds)))

    def pct(xs):
        return ", ".join(f"{100 * x:.0f} %" for x in xs)

    young = [i for i, a in enumerate(e.hp1_ages) if a < 18]
    for strat in STRATEGIES:
        behind = [rate.get(("hp1", k, "behind", strat)) for k in e.hp1_levels]
        far = [rate.get(("hp1", k, "far", strat)) for k in e.hp1_levels]
        if None not in behind:
            claim(f"HP1 tool behind high at every age ({strat})", pct(behind), min(behind) >= 0.75 - tol)
        if None in far:
            continue
        claim(f"HP1 tool far near zero at {e.hp1_ages[0]} months ({strat})", pct(far[:1]), far[0] <= 0.15 + tol)
        if None not in behind and young:
            claim(f"HP1 tool far low before 18 months against tool behind ({strat})",
                  f"{pct([far[i] for i in young])} against >= {100 * min(behind):.0f} %",
                  max(far[i] for i in young) < min(behind) - tol)
        old = [i for i in range(len(far)) if i not in young]
        if young and old:
            before, after = np.mean([far[i] for i in young]), np.mean([far[i] for i in old])
            claim(f"HP1 tool far appears from 18 months ({strat})",
                  f"{100 * before:.0f} % before, {100 * after:.0f} % after", after - before >= 0.10 - tol)
        rho = summary["checks"].get(f"hp1_far_spearman_{strat}")
        claim(f"HP1 tool far rises with skills, Spearman rho >= 0.8 ({strat})",
              f"{pct(far)}; rho {rho:.2f}" if rho is not None else pct(far), rho is not None and rho >= 0.8 - tol)
    for strat in STRATEGIES:
        for sit in e.situations:
            hp2 = [rate.get(("hp2", t, sit, strat)) for t in e.hp2_trials]
            if None in hp2 or len(hp2) < 2:
                continue
            trained = float(np.mean(hp2[1:]))
            claim(f"HP2 tool {sit} improves with training ({strat})", f"{pct(hp2)}; trained mean {100 * trained:.0f} %",
                  trained > hp2[0] + tol)
    diff = summary["checks"].get("reactive_planning_max_abs_diff")
    if diff is not None:
        claim("reactive and planning children alike (largest difference <= 25 points)", f"{100 * diff:.0f} points",
              diff <= 0.25 + tol)
    return out


ROUTES = ("pull", "moves_then_pull", "other")


def success_route(actions: str) -> str:
    """How one successful test sequence (``test_actions``, primitives joined by '>') brought the toy in.

    ``pull``: one pull (the retrieve skill, or a spare copy of it) and nothing else;
    ``moves_then_pull``: a pull as the last move, after one or more other moves (the thesis's route
    from the tool-far situation, Fig. 7.8); ``other``: the last move, the one that brought the toy
    into reach, was not a pull (touch or an interaction primitive).
    """
    moves = actions.split(">")
    if not actions or not moves[-1]:
        raise ValueError(f"empty action sequence {actions!r}")
    if not _is_pull(moves[-1]):
        return "other"
    return "pull" if len(moves) == 1 else "moves_then_pull"


def _is_pull(name: str) -> bool:
    return name.rstrip("0123456789") == "retrieve"


def success_routes(df: pd.DataFrame) -> list[dict]:
    """Per tool-far group and strategy: the number of successes and how many took each route of
    :func:`success_route` (summary.json key ``routes``)."""
    out = []
    far = df[df.situation == "far"]
    for (h, lvl, strat), g in far.groupby(["hypothesis", "level", "strategy"], sort=False):
        won = g[g.success == 1].test_actions.astype(str)
        counts = won.map(success_route).value_counts()
        row = dict(hypothesis=h, level=int(lvl), situation="far", strategy=strat, n=int(len(g)),
                   successes=int(len(won)), **{k: int(counts.get(k, 0)) for k in ROUTES})
        if "test_attempts" in g.columns:  # tests in which no PMC unit was active: the child did not move
            row["no_move"] = int((g.test_attempts == 0).sum())
        if {"routes_1", "routes_2"} <= set(g.columns):  # robots for which the world holds a 1-2 move retrieval
            row["available"] = int(((g.routes_1 + g.routes_2) > 0).sum())
        if {"imagined_1", "imagined_2", "imagined_true"} <= set(g.columns):  # ... and their mental images
            row["imagined"] = int(((g.imagined_1 + g.imagined_2) > 0).sum())
            row["imagined_true"] = int((g.imagined_true > 0).sum())
        out.append(row)
    return out


def summarise(df: pd.DataFrame, e: Exp5Config) -> dict:
    """Group rates, checks, success routes and must-show claims of the individuals in ``df``
    (the rows of individuals.csv; one run's or several runs' pooled): summary.json keys ``groups``,
    ``checks``, ``routes`` and ``claims``."""
    grp_rows = []
    for (h, lvl, sit, strat), g in df.groupby(["hypothesis", "level", "situation", "strategy"], sort=False):
        grp_rows.append(dict(hypothesis=h, level=int(lvl), age_months=int(g["age_months"].iloc[0]), situation=sit,
                             strategy=strat, n=int(len(g)), success_rate=round(float(g["success"].mean()), 4),
                             mean_skills=round(float(g["n_skills"].mean()), 3)))
    rate = group_rates(grp_rows)
    checks = {}
    for strat in STRATEGIES + ("pooled",):
        ys = [np.mean([rate.get(("hp1", k, "far", s), np.nan) for s in (STRATEGIES if strat == "pooled" else (strat,))])
              for k in e.hp1_levels]
        checks[f"hp1_far_spearman_{strat}"] = _spearman(e.hp1_levels, ys)
    diffs = [abs(rate[(h, lv, si, "reactive")] - rate[(h, lv, si, "planning")])
             for (h, lv, si, st) in rate if st == "reactive" and (h, lv, si, "planning") in rate]
    checks["reactive_planning_max_abs_diff"] = round(float(max(diffs)), 4) if diffs else None
    # how the tool-far tests were solved (thesis: pulling only after a move that brings the tool
    # behind the toy, Fig. 7.8; at 14 months "sometimes pulling after touching", l. 1692)
    routes = success_routes(df)
    young = [r for r in routes if r["hypothesis"] == "hp1" and r["level"] == e.hp1_levels[0] and r["situation"] == "far"]
    checks["hp1_far_youngest_successes"] = int(sum(r["successes"] for r in young))
    checks["hp1_far_youngest_single_pull"] = int(sum(r["pull"] for r in young))
    out = {"groups": grp_rows, "checks": checks, "routes": routes}
    out["claims"] = thesis_claims(out, e)
    return out


def evaluate(cfg, run, trained) -> dict:
    """individuals.csv, summary (docs/results.md, Experiment 5), figures and TensorBoard scalars."""
    from . import exp5_figures as figs

    e = _exp(cfg)
    results = trained["results"]
    df = pd.DataFrame([row for d in results for row in d["rows"]])
    df.insert(0, "individual", df["library"] + "_" + df["situation"])
    run.write_csv("individuals.csv", df)
    rates = summarise(df, e)
    grp_rows, checks, routes = rates["groups"], rates["checks"], rates["routes"]
    timing = [d["timing"] for d in results]
    summary = {
        "experiment": "exp5",
        "groups": grp_rows,
        "table_7_1": table_7_1(results),
        "targets": {
            "hp1/behind": {str(k): v for k, v in THESIS["hp1"]["behind"].items()},
            "hp1/far": {str(k): v for k, v in THESIS["hp1"]["far"].items()},
            "hp2/behind": {str(k): v for k, v in THESIS["hp2"]["behind"].items()},
            "hp2/far": {str(k): v for k, v in THESIS["hp2"]["far"].items()},
            "hp1_far_spearman_min": 0.8,
        },
        "checks": checks,
        "routes": routes,
        "repetitions": repetitions(cfg),
        # one individual = one robot of one group (repetition x situation), tested as both strategies
        "individuals": int(len(df) // len(STRATEGIES)),
        "environment": e.environment,
        "cost": {"tasks": len(results), "tasks_read_back": int(trained.get("read_back", 0)),
                 "libraries_reused": int(sum(bool(t.get("library_reused")) for t in timing)), "task_s_total": round(sum(t["task_s"] for t in timing), 2),
                 "task_cpu_s_total": (round(sum(t["cpu_s"] for t in timing), 2)
                                      if all("cpu_s" in t for t in timing) else None),
                 "acquisition_s_total": round(sum(t["acquisition_s"] for t in timing), 2),
                 "explore_rollouts": int(sum(t["explore_rollouts"] for t in timing)),
                 "learn_rollouts": int(sum(t["learn_rollouts"] for t in timing)),
                 "rollouts": int(sum(t.get("rollouts", 0) for t in timing)),
                 "renders": int(sum(t.get("renders", 0) for t in timing)),
                 "rollout_s": round(sum(t.get("rollout_s", 0.0) for t in timing), 2),
                 "render_s": round(sum(t.get("render_s", 0.0) for t in timing), 2)},
    }
    summary["claims"] = rates["claims"]
    for i, r in enumerate(grp_rows):
        run.logger.scalar(f"success/{r['hypothesis']}/{r['situation']}/{r['strategy']}", r["success_rate"], r["level"])
    figs.draw_all(cfg, run, df, summary, results)
    return summary


def report(cfg, run, summary) -> None:
    from . import exp5_figures as figs

    figs.write_report(cfg, run, summary)


__all__ = ["Exp5Config", "CONFIG", "train", "load", "evaluate", "report", "run_task", "groups", "tasks",
           "thesis_claims", "success_route", "success_routes", "summarise", "group_rates", "routes_available", "imagined_routes"]
