"""A learnt primitive (:class:`Skill`) and the real outcomes of sequences of primitives
(:class:`Outcomes`): what skill acquisition (Fig. 7.5) produces and action sequencing (Fig. 7.6)
performs."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import torch

from .common import N_POSTURES, Environment, Result, State


@dataclass
class Skill:
    """One learnt primitive: the event it achieves, its DMP parameters and its training history."""

    event: str
    unit: int
    theta: torch.Tensor
    found_from: int  # posture where exploration first produced the event
    competence: list[float] = field(default_factory=list)  # per epoch (successes / (4 K))
    succeeds_from: tuple[bool, ...] = (False,) * N_POSTURES  # last competence check, per posture
    log: list[tuple] = field(default_factory=list)  # ("c1", posture, signal) | ("c23", posture, State)
    copy: int = 0  # 0: the event's first skill; k: its (k+1)-th, learnt by a spare DMP

    @property
    def name(self) -> str:
        """The primitive's name in sequences and tables: the event, numbered from its second DMP on."""
        return self.event if self.copy == 0 else f"{self.event}{self.copy + 1}"



class Outcomes:
    """Deterministic real outcomes of skill sequences from an initial posture, computed once.

    ``skills`` maps each primitive's name (:attr:`Skill.name`) to its skill. The physics is
    deterministic, so the scene after primitives ``(a1, ..., an)`` (names) from posture ``p``
    depends on nothing else; every individual sharing a skill library shares this cache.
    """

    def __init__(self, env: Environment, skills: dict[str, Skill], perceive: Callable[[State], torch.Tensor]):
        self.env, self.skills, self.perceive = env, skills, perceive
        self.table: dict[tuple, Result] = {}
        self.rollouts = 0

    def after(self, posture: int, events: tuple[str, ...]) -> Result | None:
        if not events:
            return None
        key = (posture, events)
        if key not in self.table:
            prev = self.after(posture, events[:-1])
            state = self.env.start(posture) if prev is None else prev.next_state
            s = self.skills[events[-1]]
            r = self.env.execute(s.theta.unsqueeze(0), state, s.event)[0]
            if prev is not None and prev.retrieved:  # once in reach, the toy stays retrieved
                r = replace(r, events=(True,) + r.events[1:])
            self.table[key] = r
            self.rollouts += 1
        return self.table[key]

    def image(self, posture: int, events: tuple[str, ...]) -> torch.Tensor:
        r = self.after(posture, events)
        return self.perceive(self.env.start(posture) if r is None else r.next_state)
