"""Skill acquisition (thesis Fig. 7.5): exploration until a new event happens, PI^BB learning of
the primitive with the competence stopping rule, and the training of C1, C2 and C3 on the way.

The task is kept apart from the solver: what a rollout is worth for learning an event comes from
``motor.pibb.event_costs`` (0 when the event fired, else 1, the thesis's reward), and PI^BB
(``motor.pibb.PIBB``) only sees parameter vectors and their costs.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import torch

from ...motor.pibb import PIBB, event_costs
from .brain import ToolUseBrain
from .params import AcquisitionParams
from .common import EVENTS, N_POSTURES, Environment, Result, State
from .skills import Skill


@dataclass
class Library:
    """The outcome of Fig. 7.5 for one robot: skills in acquisition order, what exploration saw."""

    skills: list[Skill]
    events_seen: list[list[int]]  # [posture][event] count of exploration rollouts that fired it
    explore_rollouts: int = 0
    learn_rollouts: int = 0
    missing: list[str] = field(default_factory=list)  # enabled events never found

    def subset(self, events: Sequence[str]) -> "Library":
        keep = set(events)
        return Library([s for s in self.skills if s.event in keep], self.events_seen, self.explore_rollouts,
                       self.learn_rollouts, [e for e in self.missing if e in keep])

    def to_state(self) -> dict:
        return {"skills": [dict(event=s.event, unit=s.unit, copy=s.copy, theta=s.theta, found_from=s.found_from,
                                competence=s.competence, succeeds_from=s.succeeds_from,
                                log=[(op[0], op[1], op[2] if op[0] == "c1" else _state_tuple(op[2])) for op in s.log])
                           for s in self.skills],
                "events_seen": self.events_seen, "explore_rollouts": self.explore_rollouts,
                "learn_rollouts": self.learn_rollouts, "missing": self.missing}

    @classmethod
    def from_state(cls, d: dict) -> "Library":
        skills = [Skill(s["event"], s["unit"], s["theta"], s["found_from"], list(s["competence"]),
                        tuple(s["succeeds_from"]),
                        [(op[0], op[1], op[2] if op[0] == "c1" else State(*op[2])) for op in s["log"]],
                        s.get("copy", 0))
                  for s in d["skills"]]
        return cls(skills, d["events_seen"], d["explore_rollouts"], d["learn_rollouts"], list(d["missing"]))


def _state_tuple(s: State) -> tuple:
    return (s.posture, s.q, s.toy_xy, s.toy_yaw)


def _new_event(result: Result, wanted: Sequence[str]) -> str | None:
    fired = [e for e, f in zip(EVENTS, result.events) if f and e in wanted]
    if not fired:
        return None
    return result.fired_first if result.fired_first in fired else fired[0]


def acquire_skills(env: Environment, enabled: Sequence[str], cfg: AcquisitionParams, generator: torch.Generator,
                   brain: ToolUseBrain | None = None, perceive: Callable[[State], torch.Tensor] | None = None,
                   progress: Callable[[str], None] | None = None) -> Library:
    """Skill acquisition, Fig. 7.5, with the IM detectors ``enabled`` switched on.

    A. Exploration: every DMP starts with random parameters (``env.random_primitive``); pick a
       free DMP at random and roll it out from random initial postures, with noise added to its
       goals (``env.explore_params``), until one rollout makes a new event happen (an enabled
       detector whose skill is not yet acquired and whose distal goal, C2 -> HIP, is not already
       active for that situation). A DMP explored ``explore_patience`` times without a new event
       is given back with fresh random parameters and a free DMP is picked again; the search for
       one skill gives up after ``explore_max_rollouts``.
    B. Learning: PI^BB (eq. 7.6-7.8) from the captured parameters, K samples per posture and one
       update per posture; after each posture C1 is trained ``c1_repeats`` times with the teaching
       signal successes / K. After each epoch the mean movement is tried from the four postures:
       each success trains C2 ``c2_repeats`` times and C3 ``c3_repeats`` times. The epoch's
       competence is successes / (4 K); learning stops when it changes by less than
       ``competence_tolerance`` from the previous epoch, or after ``max_epochs``.
    The DMPs left free once every enabled event has its skill stay unused (Fig. 7.5 disables a
    detector once its skill is acquired).
    If ``brain`` is given it is trained on the way; the returned :class:`Library` also records
    every training step so that a brain can be rebuilt later (:func:`build_brain`).
    """
    perceive = perceive or env.perceive
    unknown = [e for e in enabled if e not in EVENTS]
    if unknown:
        raise ValueError(f"unknown events {unknown}; known: {EVENTS}")
    run = _Acquisition(env, cfg, generator, brain, perceive, progress)
    wanted = [e for e in EVENTS if e in enabled]
    while wanted and run.free:
        skill = run.acquire(wanted)
        if skill is None:
            run.lib.missing.extend(wanted)
            break
        wanted.remove(skill.event)  # the detector is disabled once its skill is acquired
    return run.lib


class _Acquisition:
    """The state of one :func:`acquire_skills`: the library so far, the free DMPs and their current
    random primitives, and the distal goals (C2 -> HIP) of each posture while C2 has not learnt."""

    def __init__(self, env: Environment, cfg: AcquisitionParams, generator: torch.Generator,
                 brain: ToolUseBrain | None, perceive: Callable[[State], torch.Tensor],
                 progress: Callable[[str], None] | None):
        self.env, self.cfg, self.generator = env, cfg, generator
        self.brain, self.perceive, self.progress = brain, perceive, progress
        self.lib = Library([], [[0] * len(EVENTS) for _ in range(N_POSTURES)])
        self.free = list(range(cfg.n_dmps))
        self.hip_cache: dict[int, torch.Tensor] = {}
        self.primitives = [env.random_primitive(generator) for _ in range(cfg.n_dmps)]  # "10 free DMPs", random

    def mastered(self, e: str, p: int) -> bool:
        """Whether event ``e`` is mastered from posture ``p``: its distal goal at ``hip_threshold``
        or above (without a brain: a skill of it succeeded from there)."""
        if self.brain is not None:
            if p not in self.hip_cache:
                self.hip_cache[p] = self.brain.distal_goals(self.perceive(self.env.start(p)))
            return bool(self.hip_cache[p][EVENTS.index(e)] >= self.cfg.hip_threshold)
        return any(s.event == e and s.succeeds_from[p - 1] for s in self.lib.skills)

    def acquire(self, events: list[str]) -> Skill | None:
        """One skill of one of ``events``: explored (A) on free DMPs until one fires, then learnt (B)
        and added to the library; None if the search gives up."""
        cfg, generator, free = self.cfg, self.generator, self.free
        tried, found = 0, None
        while found is None and tried < cfg.explore_max_rollouts:
            slot = free[int(torch.randint(len(free), (1,), generator=generator))]
            budget = min(cfg.explore_patience, cfg.explore_max_rollouts - tried)
            found, n = _explore(self.env, events, cfg, generator, self.lib, self.mastered, self.primitives[slot], budget)
            tried += n
            if found is None:
                self.primitives[slot] = self.env.random_primitive(generator)  # given back, drawn afresh
        if found is None:
            return None
        event, theta, p0 = found
        if self.progress:
            self.progress(f"learning {event} on DMP {slot}")
        skill = Skill(event, slot, theta, p0, copy=sum(s.event == event for s in self.lib.skills))
        _learn_skill(self.env, skill, cfg, generator, self.brain, self.perceive, self.lib)
        if self.brain is not None:
            self.brain.acquired[slot] = True
        self.hip_cache.clear()  # C2 has learnt
        self.lib.skills.append(skill)
        free.remove(slot)
        return skill


def _explore(env, events: Sequence[str], cfg: AcquisitionParams, generator, lib: Library,
             mastered: Callable[[str, int], bool], primitive: torch.Tensor, budget: int
             ) -> tuple[tuple[str, torch.Tensor, int] | None, int]:
    """Part A of Fig. 7.5 for one DMP: ``primitive`` reinitialised with a random initial posture
    and noise added to its goal (``env.explore_params``), batched; each rollout stops at the
    first new event (docs/contracts.md W10); until a rollout fires an event of ``events`` not yet mastered from its posture or
    ``budget`` rollouts are spent; the first such rollout in draw order wins, every rollout is
    counted in ``lib``. Returns ((event, parameters, posture) or None, rollouts spent)."""
    tried = 0
    while tried < budget:
        postures = torch.randint(1, N_POSTURES + 1, (min(cfg.explore_batch, budget - tried),),
                                 generator=generator).tolist()
        results: list[tuple[int, torch.Tensor, Result]] = []
        for p in sorted(set(postures)):
            idx = [i for i, q in enumerate(postures) if q == p]
            theta = env.explore_params(primitive, p, len(idx), generator)
            # the arm stops as soon as a new event happens (lines 1428, 1536-1537): the detectors
            # watched are the enabled ones whose skill is not yet acquired or mastered from p
            watched = tuple(e for e in events if not mastered(e, p)) or None
            for i, th, r in zip(idx, theta, env.execute(theta, env.start(p), watched)):
                results.append((i, th, r))
        results.sort(key=lambda t: t[0])
        found = None
        for i, th, r in results:
            tried += 1
            lib.explore_rollouts += 1
            p = postures[i]
            for k, f in enumerate(r.events):
                lib.events_seen[p - 1][k] += int(f)
            if found is None:
                e = _new_event(r, events)
                if e is not None and not mastered(e, p):
                    found = (e, th.clone(), p)
        if found is not None:
            return found, tried
    return None, tried


def _learn_skill(env, skill: Skill, cfg: AcquisitionParams, generator, brain, perceive, lib: Library) -> None:
    """Part B of Fig. 7.5 for one primitive (PI^BB + competence stopping rule)."""
    pibb = PIBB.from_sigma(skill.theta, env.search_sigma(), n_samples=cfg.pibb_samples,
                           temperature=cfg.pibb_temperature, decay=cfg.pibb_decay)
    goal = EVENTS.index(skill.event)
    total = N_POSTURES * cfg.pibb_samples
    # "the competence changes by less than the tolerance", judged on the success counts: a change
    # of exactly the tolerance (2 of 40) is not less, whatever the rounding of 2 / 40 - 0 / 40
    tolerance = round(cfg.competence_tolerance * total, 9)
    prev = None
    for epoch in range(cfg.max_epochs):
        successes = 0
        for p in range(1, N_POSTURES + 1):
            samples = pibb.sample(generator)
            results = env.execute(samples, env.start(p), skill.event)
            lib.learn_rollouts += len(samples)
            costs = event_costs(results, skill.event)  # the task's cost, apart from the solver
            pibb = pibb.update(samples, costs)
            n_ok = int((costs == 0).sum())
            successes += n_ok
            signal = n_ok / cfg.pibb_samples
            skill.log.append(("c1", p, signal))
            if brain is not None:
                seen = perceive(env.start(p))
                brain.practise_in(p, seen)
                brain.train_c1(seen, skill.unit, signal, cfg.c1_repeats)
        # competence check with the mean movement from every posture
        ok = []
        for p in range(1, N_POSTURES + 1):
            r = env.execute(pibb.mean.unsqueeze(0), env.start(p), skill.event)[0]
            lib.learn_rollouts += 1
            ok.append(bool(r.events[goal]))
            if ok[-1]:
                skill.log.append(("c23", p, r.next_state))
                if brain is not None:
                    _train_c23(brain, env, perceive, skill, p, r.next_state, cfg, generator)
        skill.succeeds_from = tuple(ok)
        skill.theta = pibb.mean.clone()
        skill.competence.append(successes / total)
        if prev is not None and abs(successes - prev) < tolerance:
            break
        prev = successes


def _train_c23(brain: ToolUseBrain, env, perceive, skill: Skill, p: int, outcome: State, cfg, generator) -> None:
    situation = perceive(env.start(p))
    brain.train_c2(situation, EVENTS.index(skill.event), cfg.c2_repeats)
    brain.train_c3(situation, skill.unit, p, perceive(outcome), cfg.c3_repeats, generator)


def build_brain(env: Environment, lib: Library, cfg: AcquisitionParams, brain: ToolUseBrain,
                generator: torch.Generator, perceive: Callable[[State], torch.Tensor] | None = None) -> ToolUseBrain:
    """Replay the C1/C2/C3 training of Fig. 7.5 for the skills of ``lib`` (in their order).

    Used when one acquired library serves several individuals (a HP1 robot keeps only the skills
    of its enabled detectors): the brain ends exactly as if only those skills had been trained.
    C3 learns a primitive's outcome only where it achieved its event (Fig. 7.5).
    """
    perceive = perceive or env.perceive
    brain.train()
    for s in lib.skills:
        brain.acquired[s.unit] = True
        for op in s.log:
            if op[0] == "c1":
                seen = perceive(env.start(op[1]))
                brain.practise_in(op[1], seen)
                brain.train_c1(seen, s.unit, op[2], cfg.c1_repeats)
            else:
                _train_c23(brain, env, perceive, s, op[1], op[2], cfg, generator)
    return brain
