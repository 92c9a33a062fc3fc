"""One task of Experiment 5: a repetition's skill libraries (one per detector set, Fig. 7.5) and
every robot built on them, trained and tested by action sequencing (Fig. 7.6).

A task is the work unit of :mod:`neuroimagery.experiments.exp5.protocol`: it runs in a worker process,
reuses that process's world, and returns (and saves) its rows, libraries, film and timing.
"""
from __future__ import annotations

import copy
import importlib
import time
from collections.abc import Sequence
from dataclasses import asdict

import numpy as np
import torch

from ...core.errors import UserInputError
from ...models.tool_use import EVENTS, Library, Outcomes, ToolUseBrain, acquire_skills, build_brain, run_trial
from ...nn.seeding import participant_seed
from . import tasks as task_files
from .config import SITUATIONS, Exp5Config
from .summary import STRATEGIES

_WORKER_ENV: dict[tuple, object] = {}  # one world per worker process, reused by its tasks


def _task_environment(e: Exp5Config):
    """This process's world for ``e`` (built once: loading the robot takes seconds), emptied of
    the previous task's image cache and timings so each task's numbers are its own."""
    key = tuple(asdict(e.world).items())
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
    w = e.world
    if w.environment == "robot":
        from ...robot.environment import ToolWorldEnvironment

        return ToolWorldEnvironment(w.world_config(), **w.env_kwargs())
    mod, _, cls = w.environment.partition(":")
    try:
        return getattr(importlib.import_module(mod), cls)()
    except (ImportError, AttributeError) as err:
        raise UserInputError(f"experiment.world.environment: cannot load {w.environment!r} ({err})") from None


def groups(e: Exp5Config) -> list[dict]:
    """Every group: hypothesis, level, age, training trials and number of detectors."""
    out = [dict(hypothesis="hp1", level=k, age_months=a, trials=e.hp1_training_trials, detectors=k)
           for k, a in zip(e.hp1_levels, e.hp1_ages)]
    out += [dict(hypothesis="hp2", level=t, age_months=a, trials=t, detectors=len(EVENTS))
            for t, a in zip(e.hp2_trials, e.hp2_ages)]
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
class _Task:
    """The caches of one task: its world, the untouched brain every robot starts from, one library
    and one built brain per detector set, and the rollouts and routes per situation and set."""

    def __init__(self, e: Exp5Config, seed: int, task: dict, library: dict | None):
        self.e, self.seed, self.task, self.r = e, seed, task, task["repetition"]
        self.env = _task_environment(e)
        self.sit_ids = [list(SITUATIONS).index(s) for s in task["situations"]]
        self.stored = {k: Library.from_state(v) for k, v in (library or {}).items()}
        self.libs: dict[str, Library] = {}
        self.fresh: list[ToolUseBrain] = []
        self.built: dict[tuple, ToolUseBrain] = {}
        self.outcomes_of: dict[tuple, Outcomes] = {}
        # per (situation, detectors): routes_1, routes_2 (the world) and imagined_1, imagined_2,
        # imagined_true (the mental images; C3 does not change in action sequencing)
        self.routes: dict[tuple, dict[str, int]] = {}
        self.t_acq = 0.0

    def new_brain(self) -> ToolUseBrain:
        # every brain of a run starts from the same seed, so a task draws C3's initial weights
        # (tens of MB) once and hands each new brain a copy of that untouched brain
        if not self.fresh:
            self.fresh.append(ToolUseBrain.from_params(self.env.image_shape, self.e.brain,
                                                       n_dmps=self.e.acquisition.n_dmps, seed=self.seed))
        return copy.deepcopy(self.fresh[0])

    def library_for(self, enabled: list[str]) -> Library:
        """Each robot acquires its library with its own enabled detectors (Fig. 7.5; docs/contracts.md
        W11): one library per detector set, shared only by the robots with the same set (the HP2
        groups and HP1's six-detector group)."""
        name = "+".join(enabled)
        if name not in self.libs:
            t1 = time.perf_counter()
            mask = sum(1 << EVENTS.index(x) for x in enabled)
            self.libs[name] = self.stored[name] if name in self.stored else acquire_skills(
                self.env, enabled, self.e.acquisition, _gen(self.seed, 1, self.r, *self.sit_ids, mask),
                brain=self.new_brain())
            self.t_acq += time.perf_counter() - t1
        return self.libs[name]

    def prepare(self, sit: str, enabled: list[str]) -> tuple[Library, Outcomes, ToolUseBrain]:
        """The library, the shared rollouts and the built brain of the robots of ``enabled`` in ``sit``,
        with the routes the world and the mental images offer from its posture."""
        sub, key, posture = self.library_for(enabled), tuple(enabled), SITUATIONS[sit]
        if (sit, key) not in self.outcomes_of:  # rollouts of this library's skills, shared by its robots
            self.outcomes_of[(sit, key)] = Outcomes(self.env, {s.name: s for s in sub.skills}, self.env.perceive)
        outcomes = self.outcomes_of[(sit, key)]
        if key not in self.built:
            self.built[key] = build_brain(self.env, sub, self.e.acquisition, self.new_brain(), _gen(self.seed, 3, self.r),
                                          self.env.perceive)
        if (sit, key) not in self.routes:
            r1, r2 = routes_available(outcomes, posture, [s.name for s in sub.skills])
            i1, i2, i_true = imagined_routes(self.built[key], outcomes, posture, sub.skills)
            pulls = [s.name for s in sub.skills if s.event == "retrieve"]
            # the mechanism check of the tool-far test: does a learnt pull alone bring the toy in?
            # (-1: the robot has no pull)
            pull_alone = int(any(outcomes.after(posture, (a,)).retrieved for a in pulls)) if pulls else -1
            self.routes[(sit, key)] = dict(routes_1=r1, routes_2=r2, imagined_1=i1, imagined_2=i2,
                                           imagined_true=i_true, pull_alone=pull_alone)
        return sub, outcomes, self.built[key]

    def timing(self, t0: float, c0: float, library: dict | None) -> dict:
        fresh_libs = [v for k, v in self.libs.items() if k not in self.stored]
        timing = dict(task_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0, acquisition_s=self.t_acq,
                      explore_rollouts=sum(v.explore_rollouts for v in fresh_libs),
                      learn_rollouts=sum(v.learn_rollouts for v in fresh_libs), library_reused=library is not None,
                      libraries=len(self.libs))
        timing.update({k: v for k, v in getattr(self.env, "timing", {}).items()})
        return timing


def _individual(t: _Task, sit: str, gi: int, grp: dict, strategy: str, g_ind: torch.Generator,
                enabled: list[str], film_wanted: bool) -> tuple[dict, dict | None]:
    """Train and test one robot (a fresh C4 on the built brain; only C4 learns in Fig. 7.6): its row
    of individuals.csv, and its film when ``film_wanted`` and its test succeeded where it is filmed."""
    e, posture = t.e, SITUATIONS[sit]
    sub, outcomes, brain = t.prepare(sit, enabled)
    brain.reset_c4()
    train_ok, train_q = [], []
    start, units = outcomes.image(posture, ()), [s.unit for s in sub.skills]
    for _ in range(grp["trials"]):
        rec = run_trial(brain, outcomes, sub.skills, posture, strategy, True, e.sequencing, g_ind)
        train_ok.append(rec.success if strategy == "reactive" else rec.imagined_success)
        # C4's learning curve: the largest action value of the robot's skills at the start
        train_q.append(float(brain.q_values(start)[units].max()) if units else 0.0)
    test = run_trial(brain, outcomes, sub.skills, posture, strategy, False, e.sequencing, g_ind,
                     record_frames=film_wanted)
    film = None
    if film_wanted and test.success and (sit == "far" or gi == len(groups(e)) - 1):
        film = dict(situation=sit, hypothesis=grp["hypothesis"], level=grp["level"],
                    strategy=strategy, start=_pack(outcomes.image(posture, ())),
                    frames=[dict(action=f["action"], reward=f["reward"], real=_pack(f["real"]),
                                 imagined=_pack(f["imagined"])) for f in test.frames],
                    maps=_small_maps(brain.maps({s.name: s.unit for s in sub.skills})))
    row = dict(
        hypothesis=grp["hypothesis"], level=grp["level"], age_months=grp["age_months"],
        situation=sit, strategy=strategy, repetition=t.r, library=t.task["key"],
        training_trials=grp["trials"], n_detectors=len(enabled), detectors="+".join(enabled),
        n_skills=len(sub.skills), skills="+".join(s.name for s in sub.skills),
        train_success_rate=float(np.mean(train_ok)) if train_ok else float("nan"),
        success=int(test.success), imagined_success=int(test.imagined_success),
        test_actions=">".join(test.actions), test_attempts=len(test.actions), **t.routes[(sit, tuple(enabled))],
        train_successes=">".join(str(int(ok)) for ok in train_ok),
        train_q=">".join(f"{q:.6g}" for q in train_q))
    return row, film


def run_task(e: Exp5Config, seed: int, task: dict, path: str | None = None, library: dict | None = None) -> dict:
    """Acquire one library (or take ``library``, a stored one acquired with the same settings),
    then simulate every individual built on it (all groups, strategies)."""
    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()
    t = _Task(e, seed, task, library)
    rows, film = [], None
    for sit in task["situations"]:
        for gi, grp in enumerate(groups(e)):
            g_ind = _gen(seed, 2, t.r, list(SITUATIONS).index(sit), gi)
            enabled = detectors_for(e, grp["detectors"], g_ind)
            for strategy in STRATEGIES:
                filming = film is None and t.r == e.engine.filmstrip_repetition and strategy == "planning"
                row, shot = _individual(t, sit, gi, grp, strategy, g_ind, enabled, filming)
                rows.append(row)
                film = film or shot
    six = "+".join(EVENTS)
    main_lib = t.libs.get(six) or next(iter(t.libs.values()), Library([], [[0] * len(EVENTS) for _ in range(4)]))
    # ``library``: the six-detector library (Table 7.1 from the robots' learning); ``libraries``:
    # every detector set's own library, by its detectors joined with '+'
    out = dict(task=task, rows=rows, library=main_lib.to_state(), libraries={k: v.to_state() for k, v in t.libs.items()},
               film=film, timing=t.timing(t0, c0, library), config=asdict(e), seed=seed)
    if path is not None:
        task_files.save(out, path)
    return out
