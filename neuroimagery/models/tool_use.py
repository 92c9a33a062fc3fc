"""The tool-use development model of thesis chapter 7 (Fig. 7.4) and its two algorithms.

Maps (Fig. 7.4)
    V1 / PC   the eye image and its colour-filtered version: two 240 x 320 channels (red toy,
              green rake) flattened to one vector ``x`` (the environment renders them).
    PMC       10 units, one affordance per motor primitive; PMC unit ``j`` drives M1 unit ``j``
              (a fixed one-to-one link, not a connection).
    M1        10 DMPs (eq. 7.2-7.5), free until a skill is learnt on them.
    HIP       6 distal-goal units, one per intrinsically motivating event.
    PFC       the mental image: an imagined PC pattern.

Connections
    C1  PC -> PMC   Hebbian (outstar, eq. 4.2-4.3) with the teaching signal successes / K of
                    one PI^BB update; read out as the mean weight over the active PC units, so an
                    affordance lies in [0, 1].
    C2  PC -> HIP   Hebbian (outstar) with teaching signal 1 when a skill succeeds from a posture.
    C3  PMC <-> PFC bidirectional supervised SOM (``nn.som.BidirectionalSOM``): a unit per
                    (posture, primitive) pair keeps the situation image plus the primitive's code
                    on one side and the outcome image on the other; run backwards (situation +
                    intended action -> outcome) it yields the mental image, the perceived scene
                    being first recognised as one of the initial situations (``c3_recall``).
    C4  PC -> PMC   Q-learning (eq. 7.1, ``nn.rules.QLearning``), standard sign by default.

Algorithms
    :func:`acquire_skills`  skill acquisition, Fig. 7.5 (exploration, PI^BB learning with the
                            competence stopping rule, training of C1, C2, C3).
    :func:`sequence_trial`  action sequencing, Fig. 7.6 (softmax over C1 + C4, a reactive child
                            moves, a planning child imagines the outcome through C3, Q-learning).

The model talks to the world through the small :class:`Environment` protocol, so the same code
runs on the pybullet rake-and-toy world (:class:`ToolWorldEnvironment`) and on cheap stand-ins
in the tests.  Weight tensors live in buffers of :class:`ToolUseBrain` (one individual).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, Sequence

import numpy as np
import torch
from torch import nn

from ..motor.pibb import PIBB
from ..nn.connections import AllToAll
from ..nn.functional import softmax_select
from ..nn.rules import Hebbian, QLearning
from ..nn.som import BidirectionalSOM

EVENTS = ("retrieve", "touch", "south", "north", "west", "east")  # thesis Fig. 7.3 / Table 7.1 order
SKILL_LETTERS = ("P", "T", "S", "N", "W", "E")  # Table 7.1 column names of the skills
N_POSTURES = 4
# the values each modelling switch of this module accepts (Exp5Config checks the same table)
CHOICES = {"c3_recall": ("practised", "situation", "joint"), "planning_test": ("act", "plan"),
           "goal_frame": ("relative", "absolute"), "reach_bound": ("path", "goal"),
           "spare_dmps": ("none", "unmastered"), "c3_outcomes": ("success", "every"),
           "pibb_flat": ("average", "keep"), "toy_turn": ("keep", "reset")}


def check_choice(key: str, value) -> None:
    """Raise ``ValueError`` naming ``key`` when ``value`` is not one of ``CHOICES[key]``."""
    if value not in CHOICES[key]:
        raise ValueError(f"{key} must be one of {', '.join(map(repr, CHOICES[key]))}, got {value!r}")


# ---------------------------------------------------------------------------------- environment
@dataclass(frozen=True)
class State:
    """A scene: the initial posture it started from, and (after moves) the arm and toy state.

    ``q`` / ``toy_xy`` are None for the untouched initial situation of ``posture``; ``toy_yaw`` is
    the toy's turn about the vertical (rad), None when it is square (or not tracked).
    """

    posture: int
    q: tuple[float, ...] | None = None
    toy_xy: tuple[float, float] | None = None
    toy_yaw: float | None = None


@dataclass(frozen=True)
class Result:
    """What executing one primitive did: events (``EVENTS`` order), the state it left."""

    events: tuple[bool, ...]
    next_state: State
    fired_first: str | None = None

    @property
    def retrieved(self) -> bool:
        return bool(self.events[0])


class Environment(Protocol):
    """What the brain needs from a world (the pybullet robot or a stand-in).

    image_shape: (H, W) of one PC channel; the PC vector has ``2 * H * W`` units (toy, tool).
    n_params: length of a primitive's flat parameter vector.
    """

    image_shape: tuple[int, int]
    n_params: int

    def start(self, posture: int) -> State: ...

    def random_params(self, posture: int, n: int, generator: torch.Generator) -> torch.Tensor:
        """``n`` random movements around ``posture`` (the exploration step of Fig. 7.5)."""

    def search_sigma(self) -> torch.Tensor:
        """Standard deviation of the PI^BB exploration noise per parameter (eq. 7.6)."""

    def execute(self, params: torch.Tensor, state: State, watched: str | None) -> list[Result]:
        """Run each parameter row from ``state``; stop a row when ``watched`` fires."""

    def perceive(self, state: State) -> torch.Tensor:
        """The PC map of a state: float (2, H, W) in [0, 1] (toy channel, tool channel)."""

    def reward(self, image: torch.Tensor) -> float:
        """The toy-related reward read from a PC image: 1 if the toy lies in reach, else 0."""


# ---------------------------------------------------------------------------------- the brain
class GatedHebbian(Hebbian):
    """Outstar Hebbian change (eq. 4.2-4.3) restricted to the rows of the unit being trained.

    Fig. 7.5 trains C1 (and C2) for one primitive (one goal) at a time; the other units' weights
    must keep what they learnt, so the change is masked by ``gate`` ``(P, out)``.
    """

    def delta(self, weight, pre, post, gate=None, repeats: int = 1, **kw):
        """``repeats`` > 1: the change of that many identical steps in one go. With binary
        input (as the PC map is) ``k`` outstar steps give ``(1 - (1 - eta)^k) / eta`` times the
        one-step change, exactly."""
        d = super().delta(weight, pre=pre, post=post)
        if repeats > 1:
            if not bool(((pre == 0) | (pre == 1)).all()):
                raise ValueError("GatedHebbian: repeats > 1 needs binary input")
            d = d * ((1.0 - (1.0 - self.eta) ** repeats) / self.eta)
        return d if gate is None else d * gate.unsqueeze(-1)


class ToolUseBrain(nn.Module):
    """One infant robot's maps and connections C1-C4 (Fig. 7.4)."""

    def __init__(self, image_shape: tuple[int, int], n_dmps: int = 10, n_goals: int = 6,
                 c1_eta: float = 0.1, c2_eta: float = 0.1, c3_eta: float = 0.1, c3_sigma: float = 0.1,
                 c3_action_gain: float = 100.0, q_eta: float = 1e-4, q_gamma: float = 0.8,
                 q_form: str = "standard", c3_recall: str = "practised", seed: int = 0) -> None:
        super().__init__()
        check_choice("c3_recall", c3_recall)
        self.c3_recall = c3_recall
        self.image_shape = tuple(image_shape)
        self.n_pc = 2 * image_shape[0] * image_shape[1]
        self.n_dmps, self.n_goals = int(n_dmps), int(n_goals)
        self.c3_action_gain = float(c3_action_gain)
        self.c1 = AllToAll(self.n_pc, n_dmps, init="zeros", rules=GatedHebbian(c1_eta), name="C1")
        self.c2 = AllToAll(self.n_pc, n_goals, init="zeros", rules=GatedHebbian(c2_eta), name="C2")
        self.c4 = AllToAll(self.n_pc, n_dmps, init="zeros", rules=QLearning(q_eta, q_gamma, q_form), name="C4")
        # C3: a = outcome image (PFC), b = [situation image, gain * primitive code] (PC + PMC)
        self.c3 = BidirectionalSOM(N_POSTURES * n_dmps, self.n_pc, self.n_pc + n_dmps, seed=seed, eta=c3_eta,
                                   sigma=c3_sigma, iterations=1, name="C3")
        self.register_buffer("acquired", torch.zeros(n_dmps, dtype=torch.bool))  # M1 units holding a skill
        self.register_buffer("c3_trained", torch.zeros(N_POSTURES * n_dmps, dtype=torch.bool))
        # the initial situations practised in (Fig. 7.5 B: every posture, success or not)
        self.register_buffer("practised", torch.zeros(N_POSTURES, self.n_pc))
        self.register_buffer("practised_seen", torch.zeros(N_POSTURES, dtype=torch.bool))
        self._b_norms: torch.Tensor | None = None  # cache of C3's input-side prototype norms
        self._s_norms: torch.Tensor | None = None  # cache of the norms of their situation parts

    # --- read-outs
    @staticmethod
    def flat(image: torch.Tensor) -> torch.Tensor:
        return image.reshape(1, -1).float()

    # The read-outs and updates below work on the weight rows directly (``weight[0]`` is the one
    # participant's matrix): the same numbers as going through ``AllToAll`` / ``BidirectionalSOM``
    # (the tests compare them), without the generic shape and finiteness checks over the
    # 153 600-unit PC map that dominated the cost of a run.
    def affordance(self, image: torch.Tensor) -> torch.Tensor:
        """C1: mean weight over the active PC units -> (n_dmps,) in [0, 1]."""
        x = self.flat(image)[0]
        return (self.c1.weight[0] @ x) / x.sum().clamp_min(1.0)

    def distal_goals(self, image: torch.Tensor) -> torch.Tensor:
        """C2 -> HIP activity (6,) in [0, 1]: which goals this situation is known to afford."""
        x = self.flat(image)[0]
        return (self.c2.weight[0] @ x) / x.sum().clamp_min(1.0)

    def q_values(self, image: torch.Tensor) -> torch.Tensor:
        """C4 -> (n_dmps,) action values."""
        return self.c4.weight[0] @ self.flat(image)[0]

    def pmc(self, image: torch.Tensor) -> torch.Tensor:
        """PMC activity: affordance (C1) plus learnt action value (C4), Fig. 7.6."""
        return self.affordance(image) + self.q_values(image)

    def _c3_b(self, image: torch.Tensor, unit: int) -> torch.Tensor:
        code = torch.zeros(1, self.n_dmps)
        code[0, unit] = self.c3_action_gain
        return torch.cat([self.flat(image), code], dim=1)

    def _c3_b_norms(self) -> torch.Tensor:
        """Squared norms of C3's input-side prototypes (cached until C3 learns again)."""
        if getattr(self, "_b_norms", None) is None:
            w = self.c3.som.weight[0, :, self.n_pc:]
            self._b_norms = (w * w).sum(-1)
        return self._b_norms

    def _c3_s_norms(self) -> torch.Tensor:
        """Squared norms of the situation parts of C3's input-side prototypes (cached)."""
        if getattr(self, "_s_norms", None) is None:
            w = self.c3.som.weight[0, :, self.n_pc: 2 * self.n_pc]
            self._s_norms = (w * w).sum(-1)
        return self._s_norms

    def recall_unit(self, image: torch.Tensor, unit: int) -> int:
        """The C3 unit that answers "what if I do primitive ``unit`` in situation ``image``".

        ``c3_recall = "practised"``: the perceived scene is recognised first, as the nearest of the
        initial situations the robot practised in (all it met in Fig. 7.5 B, whether a movement
        succeeded there or not); the answer is that situation's unit for the intended primitive,
        trained or not. ``"situation"``: the same, but only among the situations stored in C3
        (those where some primitive succeeded).  ``"joint"``: the unit whose
        input side [situation, gain * primitive code] is nearest (the primitive's code dominates,
        so any situation where the primitive ever succeeded can answer).
        """
        w = self.c3.som.weight[0]
        if self.c3_recall == "joint":
            b = self._c3_b(image, unit)[0]
            return int((self._c3_b_norms() - 2.0 * (w[:, self.n_pc:] @ b)).argmin())
        if self.c3_recall == "practised":  # rows: the practised initial situations
            rows, norms, known, per_situation = self.practised, (self.practised ** 2).sum(-1), self.practised_seen, 1
        else:  # rows: the situation parts of C3's trained prototypes
            rows, norms, known, per_situation = w[:, self.n_pc: 2 * self.n_pc], self._c3_s_norms(), self.c3_trained, self.n_dmps
        if not bool(known.any()):
            return unit
        d = norms - 2.0 * (rows @ self.flat(image)[0])  # squared distance up to the image's own norm
        d = torch.where(known, d, torch.full_like(d, float("inf")))
        return int(d.argmin()) // per_situation * self.n_dmps + int(unit)

    def imagine(self, image: torch.Tensor, unit: int) -> torch.Tensor:
        """C3 run backwards: the mental image of doing primitive ``unit`` in situation ``image``.

        The unit found by :meth:`recall_unit` gives its outcome prototype; a unit never trained
        means nothing was learnt for that situation and primitive: no change is imagined.
        """
        winner = self.recall_unit(image, unit)
        if not bool(self.c3_trained[winner]):
            return image.reshape(2, *self.image_shape).float().clone()
        w = self.c3.som.weight[0]
        return w[winner, : self.n_pc].reshape(2, *self.image_shape).clamp(0.0, 1.0)

    def maps(self, skills: dict[str, int]) -> dict[str, torch.Tensor]:
        """The learnt weights as images, for TensorBoard: one (H, 2W) map per connection and unit,
        the toy channel of the PC on the left and the tool channel on the right.

        ``C1/<skill>`` (affordance: which PC pixels drive the skill's PMC unit), ``C4/<skill>``
        (its action value), ``C2/<event>`` (distal goals) and ``C3/posture-<p>/<skill>`` (the
        stored outcome image, the mental image of doing the skill in situation p; trained units
        only). ``skills`` maps a skill's name to its PMC unit.
        """
        H, W = self.image_shape

        def side_by_side(row: torch.Tensor) -> torch.Tensor:
            m = row.reshape(2, H, W)
            return torch.cat([m[0], m[1]], dim=1).clone()

        out = {}
        for name, unit in skills.items():
            out[f"C1/{name}"] = side_by_side(self.c1.weight[0, unit])
            out[f"C4/{name}"] = side_by_side(self.c4.weight[0, unit])
        for k in range(self.n_goals):
            out[f"C2/{EVENTS[k] if k < len(EVENTS) else k}"] = side_by_side(self.c2.weight[0, k])
        w = self.c3.som.weight[0]
        for name, unit in skills.items():
            for posture in range(1, N_POSTURES + 1):
                label = (posture - 1) * self.n_dmps + unit
                if bool(self.c3_trained[label]):
                    out[f"C3/posture-{posture}/{name}"] = side_by_side(w[label, : self.n_pc].clamp(0.0, 1.0))
        return out

    def reset_c4(self) -> None:
        """Forget all action values (C4 back to its zero start): a fresh individual's C4."""
        self.c4.weight.zero_()

    # --- learning (Fig. 7.5 and 7.6)
    @staticmethod
    def _outstar_row(row: torch.Tensor, x: torch.Tensor, target: float, eta: float, times: int) -> None:
        """``times`` outstar steps (eq. 4.2-4.3) on one output unit's row: w += eta x (y - w).

        Binary input (the PC map): closed form, ``w <- y + (1 - eta)^times (w - y)`` where x = 1."""
        if times < 1:
            return
        if bool(((x == 0) | (x == 1)).all()):
            on = x > 0
            row[on] = target + (1.0 - eta) ** times * (row[on] - target)
        else:
            for _ in range(times):
                row.add_(eta * x * (target - row))

    @torch.no_grad()
    def train_c1(self, image: torch.Tensor, unit: int, signal: float, times: int) -> None:
        """C1 trained for primitive ``unit`` only (the other rows keep what they learnt)."""
        if self.c1.training:
            self._outstar_row(self.c1.weight[0, unit], self.flat(image)[0], float(signal), self.c1.rules[0].eta, times)

    @torch.no_grad()
    def practise_in(self, posture: int, image: torch.Tensor) -> None:
        """Remember initial situation ``posture`` as seen (for C3's situation recognition)."""
        self.practised[posture - 1] = self.flat(image)[0]
        self.practised_seen[posture - 1] = True

    @torch.no_grad()
    def train_c2(self, image: torch.Tensor, goal: int, times: int) -> None:
        """C2 trained toward distal goal ``goal`` with teaching signal 1."""
        if self.c2.training:
            self._outstar_row(self.c2.weight[0, goal], self.flat(image)[0], 1.0, self.c2.rules[0].eta, times)

    @torch.no_grad()
    def train_c3(self, image: torch.Tensor, unit: int, posture: int, outcome: torch.Tensor, times: int,
                 generator: torch.Generator) -> None:
        label = (posture - 1) * self.n_dmps + unit
        a, b = self.flat(outcome).unsqueeze(0), self._c3_b(image, unit).unsqueeze(0)
        if not self.training or times < 1:
            return
        rule = self.c3.som.rule
        eta, sigma = rule.schedule(0)
        theta = rule.neighbourhood(self.c3.som.grid, torch.tensor([label]), sigma)[0]
        if int((theta > 0).sum()) == 1:
            # the neighbourhood is below the rule's cutoff: ``times`` online steps of eq. 4.5 with
            # the forced winner move only the winner's row, w <- x + (1 - eta)^times (w - x)
            w = self.c3.som.weight[0, label]
            x = torch.cat([a, b], dim=-1)[0, 0]
            w.copy_(x + (1.0 - float(eta)) ** times * (w - x))
            self.c3.som.steps += times
            self._b_norms = self._s_norms = None
        else:
            self.c3.fit(a, b, labels=torch.tensor([[label]]), iterations=times,
                        order=torch.zeros(1, times, dtype=torch.long))
            self._b_norms = self._s_norms = None
        self.c3_trained[label] = True

    @torch.no_grad()
    def q_update(self, x0: torch.Tensor, unit: int, reward: float, x1: torch.Tensor, done: bool) -> None:
        """Eq. 7.1 on C4 for the transition ``x0 --unit--> x1``: only the row of ``unit`` changes,
        ``w += eta (r +- gamma qMax(x1) - q_unit(x0)) x0`` (``nn.rules.QLearning`` for one sample)."""
        if not self.c4.training:
            return
        rule = self.c4.rules[0]
        a, b = self.flat(x0)[0], self.flat(x1)[0]
        w = self.c4.weight[0]
        q_max = 0.0 if done else float((w @ b).max())
        sign = 1.0 if rule.form == "standard" else -1.0
        err = float(reward) + sign * rule.gamma * q_max - float(w[unit] @ a)
        w[unit].add_(a, alpha=rule.eta * err)

    def reset_state(self) -> None:
        """The brain keeps no activity between trials."""


# ---------------------------------------------------------------------------------- skills
@dataclass
class AcquisitionConfig:
    """Parameters of Fig. 7.5 (see ``experiments/exp5.Exp5Config`` for their meaning)."""

    n_dmps: int = 10
    pibb_samples: int = 10
    pibb_temperature: float = 0.1
    pibb_decay: float = 0.9
    pibb_flat: str = "average"
    max_epochs: int = 10
    competence_tolerance: float = 0.05
    c1_repeats: int = 10
    c2_repeats: int = 10
    c3_repeats: int = 50
    hip_threshold: float = 0.5
    explore_batch: int = 8
    explore_max_rollouts: int = 400
    # the DMPs left free once every enabled event has its skill: 'none' = unused | 'unmastered' =
    # exploration goes on, and an enabled event firing from a situation whose distal goal (HIP) is
    # not active there is learnt again by a free DMP (thesis: the extra DMPs serve events one DMP
    # cannot achieve from every initial posture)
    spare_dmps: str = "none"
    # what C3 holds: 'success' = a primitive's outcome from an initial situation only where it achieved
    # its event (Fig. 7.5) | 'every' = also, from the other initial situations, the outcome of the
    # learnt primitive performed there (the movement runs to its end); applied by build_brain
    c3_outcomes: str = "success"

    def __post_init__(self) -> None:
        check_choice("spare_dmps", self.spare_dmps)
        check_choice("c3_outcomes", self.c3_outcomes)


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


def acquire_skills(env: Environment, enabled: Sequence[str], cfg: AcquisitionConfig, generator: torch.Generator,
                   brain: ToolUseBrain | None = None, perceive: Callable[[State], torch.Tensor] | None = None,
                   progress: Callable[[str], None] | None = None) -> Library:
    """Skill acquisition, Fig. 7.5, with the IM detectors ``enabled`` switched on.

    A. Exploration: pick a free DMP at random; roll out random movements from random initial
       postures until one makes a new event happen (an enabled detector whose skill is not yet
       acquired and whose distal goal, C2 -> HIP, is not already active for that situation).
    B. Learning: PI^BB (eq. 7.6-7.8) from the captured parameters, K samples per posture and one
       update per posture; after each posture C1 is trained ``c1_repeats`` times with the teaching
       signal successes / K. After each epoch the mean movement is tried from the four postures:
       each success trains C2 ``c2_repeats`` times and C3 ``c3_repeats`` times. The epoch's
       competence is successes / (4 K); learning stops when it changes by less than
       ``competence_tolerance`` from the previous epoch, or after ``max_epochs``.
    With ``cfg.spare_dmps == "unmastered"``, once every enabled event has a skill the free DMPs go on
    exploring: an enabled event that fires from a situation where it is not yet mastered (its
    distal goal below ``hip_threshold`` there; without a brain: no skill of it succeeded from that
    posture) is learnt again, by A and B, as a further skill of that event.
    If ``brain`` is given it is trained on the way; the returned :class:`Library` also records
    every training step so that a brain can be rebuilt later (:func:`build_brain`).
    """
    perceive = perceive or env.perceive
    unknown = [e for e in enabled if e not in EVENTS]
    if unknown:
        raise ValueError(f"unknown events {unknown}; known: {EVENTS}")
    lib = Library([], [[0] * len(EVENTS) for _ in range(N_POSTURES)])
    free = list(range(cfg.n_dmps))
    wanted = [e for e in EVENTS if e in enabled]
    hip_cache: dict[int, torch.Tensor] = {}

    def mastered(e: str, p: int) -> bool:
        if brain is not None:
            if p not in hip_cache:
                hip_cache[p] = brain.distal_goals(perceive(env.start(p)))
            return bool(hip_cache[p][EVENTS.index(e)] >= cfg.hip_threshold)
        return any(s.event == e and s.succeeds_from[p - 1] for s in lib.skills)

    def acquire(slot: int, events: list[str]) -> Skill | None:
        found = _explore(env, events, cfg, generator, lib, mastered)
        if found is None:
            return None
        event, theta, p0 = found
        if progress:
            progress(f"learning {event} on DMP {slot}")
        skill = Skill(event, slot, theta, p0, copy=sum(s.event == event for s in lib.skills))
        _learn_skill(env, skill, cfg, generator, brain, perceive, lib)
        if brain is not None:
            brain.acquired[slot] = True
        hip_cache.clear()  # C2 has learnt
        lib.skills.append(skill)
        free.remove(slot)
        return skill

    while wanted and free:
        skill = acquire(free[int(torch.randint(len(free), (1,), generator=generator))], wanted)
        if skill is None:
            lib.missing.extend(wanted)
            break
        wanted.remove(skill.event)  # the detector is disabled once its skill is acquired
    if cfg.spare_dmps == "unmastered":
        again = [e for e in EVENTS if e in enabled and e not in lib.missing]
        while again and free:
            if acquire(free[int(torch.randint(len(free), (1,), generator=generator))], again) is None:
                break
    return lib


def _explore(env, events: Sequence[str], cfg: AcquisitionConfig, generator, lib: Library,
             mastered: Callable[[str, int], bool]) -> tuple[str, torch.Tensor, int] | None:
    """Part A of Fig. 7.5: random movements from random postures (batched) until one fires an
    event of ``events`` not yet mastered from its posture; the first such rollout in draw order
    wins, every rollout is counted in ``lib``. Returns (event, parameters, posture) or None."""
    tried = 0
    while tried < cfg.explore_max_rollouts:
        postures = torch.randint(1, N_POSTURES + 1, (cfg.explore_batch,), generator=generator).tolist()
        results: list[tuple[int, torch.Tensor, Result]] = []
        for p in sorted(set(postures)):
            idx = [i for i, q in enumerate(postures) if q == p]
            theta = env.random_params(p, len(idx), generator)
            for i, th, r in zip(idx, theta, env.execute(theta, env.start(p), None)):
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
            return found
    return None


def _learn_skill(env, skill: Skill, cfg: AcquisitionConfig, generator, brain, perceive, lib: Library) -> None:
    """Part B of Fig. 7.5 for one primitive (PI^BB + competence stopping rule)."""
    pibb = PIBB.from_sigma(skill.theta, env.search_sigma(), n_samples=cfg.pibb_samples,
                           temperature=cfg.pibb_temperature, decay=cfg.pibb_decay, flat=cfg.pibb_flat)
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
            costs = torch.tensor([0.0 if r.events[goal] else 1.0 for r in results])
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


def build_brain(env: Environment, lib: Library, cfg: AcquisitionConfig, brain: ToolUseBrain,
                generator: torch.Generator, perceive: Callable[[State], torch.Tensor] | None = None,
                outcomes: Outcomes | None = None) -> ToolUseBrain:
    """Replay the C1/C2/C3 training of Fig. 7.5 for the skills of ``lib`` (in their order).

    Used when one acquired library serves several individuals (a HP1 robot keeps only the skills
    of its enabled detectors): the brain ends exactly as if only those skills had been trained.
    With ``cfg.c3_outcomes == "every"`` the primitives are also performed from the initial
    situations where they missed their event, through ``outcomes`` (the rollout cache shared with
    action sequencing) when given.
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
        if cfg.c3_outcomes == "every":
            # the learnt movement from the initial situations where it did not achieve its event
            # (the last competence check): C3 learns where it leads there, C2 learns nothing
            for p in range(1, N_POSTURES + 1):
                if not s.succeeds_from[p - 1]:
                    r = (outcomes.after(p, (s.name,)) if outcomes is not None  # cached, shared with sequencing
                         else env.execute(s.theta.unsqueeze(0), env.start(p), s.event)[0])
                    brain.train_c3(perceive(env.start(p)), s.unit, p, perceive(r.next_state), cfg.c3_repeats,
                                   generator)
    return brain


# ---------------------------------------------------------------------------------- sequencing
@dataclass
class TrialRecord:
    """One action-sequencing trial (Fig. 7.6)."""

    actions: list[str]
    rewards: list[float]
    success: bool  # the toy was really retrieved
    imagined_success: bool = False  # planning: the plan reached the goal in mind
    frames: list[dict] = field(default_factory=list)  # optional film strip (real / imagined PC)


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
                r = Result((True,) + r.events[1:], r.next_state, r.fired_first)
            self.table[key] = r
            self.rollouts += 1
        return self.table[key]

    def image(self, posture: int, events: tuple[str, ...]) -> torch.Tensor:
        r = self.after(posture, events)
        return self.perceive(self.env.start(posture) if r is None else r.next_state)


def sequence_trial(brain: ToolUseBrain, outcomes: Outcomes, skills: Sequence[Skill], posture: int, strategy: str,
                   training: bool, attempts: int, temperature: float, generator: torch.Generator,
                   record_frames: bool = False, planning_test: str = "act",
                   active_threshold: float = 0.0) -> TrialRecord:
    """One trial of Fig. 7.6 from initial posture ``posture``.

    Each attempt: feed the current PC image through C1 and C4, pick one acquired PMC unit with
    softmax (among the active ones, ``active_threshold``), then a reactive child performs the
    primitive (the real scene is perceived next) while a planning child imagines it through C3
    (the mental image becomes the next input). The toy-related reward is read from that next
    image (reactive: the retrieve detector). In training mode C4 learns by eq. 7.1; a planning
    child trains in mind only.

    The test (``training`` False) of a planning child, ``planning_test``:

    * ``"act"``: every attempt starts from the real scene: the child chooses from what it sees
      (C1 + the C4 it learnt in mind), imagines the outcome, performs the primitive and looks
      again; it stops once the toy is really in reach.
    * ``"plan"``: the whole plan (up to ``attempts`` primitives, until the mental image shows the
      toy in reach) is made in mind from the initial image, then performed for real.

    Test success is always the real retrieval.

    ``active_threshold``: Fig. 7.6 draws among the *active* PMC units; with a threshold above 0
    only the acquired units whose PMC activity (C1 + C4) exceeds it are candidates, and a child
    with no active unit does not move (the trial ends). 0 (this function's default): every
    acquired unit is a candidate; Experiment 5 uses ``Exp5Config.active_threshold`` (0.1).
    """
    if strategy not in ("reactive", "planning"):
        raise ValueError(f"strategy must be 'reactive' or 'planning', got {strategy!r}")
    check_choice("planning_test", planning_test)
    env = outcomes.env
    units = torch.tensor([s.unit for s in skills])
    by_unit = {s.unit: s for s in skills}
    done_events: tuple[str, ...] = ()
    x0 = outcomes.image(posture, ())
    rec = TrialRecord([], [], False)
    if len(skills) == 0:
        return rec
    brain.train(training)
    acting = strategy == "reactive" or (not training and planning_test == "act")
    imagining = strategy == "planning"
    for _ in range(attempts):
        act = brain.pmc(x0)[units]
        if active_threshold > 0:
            active = act > active_threshold
            if not bool(active.any()):
                break  # nothing afforded here: the child does not move
            act = act.masked_fill(~active, float("-inf"))
        k = int(softmax_select(act.view(1, -1), temperature, generators=[generator])[0])
        skill = by_unit[int(units[k])]
        done_events = done_events + (skill.name,)
        imagined = brain.imagine(x0, skill.unit) if imagining or record_frames else None
        if imagining and float(env.reward(imagined)) > 0:
            rec.imagined_success = True
        if acting:
            r = outcomes.after(posture, done_events)
            x1 = outcomes.perceive(r.next_state)
            reward = 1.0 if r.retrieved else 0.0
        else:
            x1 = imagined
            reward = float(env.reward(x1))
        rec.actions.append(skill.name)
        rec.rewards.append(reward)
        if record_frames:
            rec.frames.append({"action": skill.name, "real": outcomes.image(posture, done_events),
                               "imagined": imagined, "reward": reward})
        if training:
            brain.q_update(x0, skill.unit, reward, x1, done=reward > 0)
        x0 = x1
        if reward > 0:
            break
    if acting:
        rec.success = bool(rec.rewards and rec.rewards[-1] > 0)
    else:
        rec.imagined_success = bool(rec.rewards and rec.rewards[-1] > 0)
        # "plan" test: the plan is performed for real (prefixes are cached); stop once the toy is in reach
        for n in range(1, 0 if training else len(rec.actions) + 1):
            if outcomes.after(posture, tuple(rec.actions[:n])).retrieved:
                rec.success = True
                break
    brain.eval()
    return rec


# ---------------------------------------------------------------------------------- the robot
class ToolWorldEnvironment:
    """:class:`Environment` over the pybullet rake-and-toy world (``robot.world.ToolWorld``).

    Primitives are DMPs (``motor.dmp.DMP``, 7 goals + 28 shape weights) rolled out from the
    arm's current joints. A scene after earlier moves (arm elsewhere, toy displaced) is restored
    through ``ToolWorld.reset(q=..., toy_xy=..., toy_yaw=...)`` before the next rollout.

    ``toy_turn`` says whether a scene keeps the toy's turn about the vertical: ``"keep"`` (the toy
    is put back as the last move left it, the default) or ``"reset"`` (square again; the toy's
    place is kept either way). A rollout from an initial situation is the same under both.

    ``goal_frame`` says what the 7 goal numbers of a primitive mean:

    * ``"relative"``: the joint displacement from wherever the arm starts (goal = start + offset).
      The primitive is then one movement *shape*, translated in joint space: since the DMP's
      forcing term scales with ``g - y0`` (eq. 7.3), the same parameters give the same joint
      trajectory relative to the start from every posture, and what it does to the toy depends on
      where the rake starts (the situation).
    * ``"absolute"``: joint angles; every rollout of a primitive ends in the same arm posture
      whatever the start, and its shape is rescaled by ``g - y0``.

    Exploration draws goals as the start posture plus noise (clipped to the joint limits) in both
    frames, so a discovered movement is the same either way; the frames differ only in how a
    learnt primitive is replayed from another posture or after earlier moves.

    ``reach_bound`` says how the reach of one movement (``DMP.max_goal_offset``, the world's
    ``max_goal_offset_rad``) is enforced: ``"path"`` keeps every joint within it of its start at
    every step; ``"goal"`` bounds only the DMP goal, so the shape term can carry a joint farther on
    the way (learnt skills: a median 0.32 rad, some 0.6 rad, against the 0.15 rad bound).
    """

    def __init__(self, world_config=None, duration_s: float = 1.5, explore_goal_sigma: float = 0.35,
                 explore_weight_sigma: float = 300.0, search_goal_sigma: float = 0.05,
                 search_weight_sigma: float = 30.0, goal_frame: str = "absolute", reach_bound: str = "goal",
                 toy_turn: str = "keep") -> None:
        from ..motor.dmp import DMP
        from ..robot.world import ToolWorld

        class _World(ToolWorld):
            """ToolWorld whose rollouts can start from a given arm and toy state."""

            start_state: tuple | None = None

            def reset(self, posture, q=None, toy_xy=None, toy_yaw=None):
                if q is None and toy_xy is None and self.start_state is not None:
                    q, toy_xy, toy_yaw = self.start_state
                super().reset(posture, q=q, toy_xy=toy_xy, toy_yaw=toy_yaw)

        check_choice("goal_frame", goal_frame)
        check_choice("reach_bound", reach_bound)
        check_choice("toy_turn", toy_turn)
        self.goal_frame, self.reach_bound, self.toy_turn = goal_frame, reach_bound, toy_turn
        self.world = _World(world_config)
        self.dmp = DMP()
        self.n_params = self.dmp.n_params
        cfg = self.world.cfg
        self.image_shape = (cfg.image_height, cfg.image_width)
        self.duration_s, self.dt = float(duration_s), float(cfg.control_dt)
        self.explore = (float(explore_goal_sigma), float(explore_weight_sigma))
        J, B = self.dmp.n_joints, self.dmp.n_basis
        self._sigma = torch.cat([torch.full((J,), float(search_goal_sigma)), torch.full((J * B,), float(search_weight_sigma))])
        self._images: dict[State, torch.Tensor] = {}
        self._inv: np.ndarray | None = None
        self._bias: float | None = None  # the toy reader's mean error at the reachable area's border (m)
        self.timing = {"rollout_s": 0.0, "render_s": 0.0, "rollouts": 0, "renders": 0}

    def close(self) -> None:
        self.world.close()

    def start(self, posture: int) -> State:
        return State(int(posture))

    def _q(self, state: State) -> torch.Tensor:
        return self.world.initial_posture(state.posture) if state.q is None else torch.tensor(state.q)

    def random_params(self, posture: int, n: int, generator: torch.Generator) -> torch.Tensor:
        q0 = self.world.initial_posture(posture)
        gs, ws = self.explore
        goals = self.world.kin.clamp(q0 + gs * torch.randn(n, 7, generator=generator))
        if self.goal_frame == "relative":
            goals = goals - q0
        weights = ws * torch.randn(n, 7, self.dmp.n_basis, generator=generator)
        return self.dmp.pack(goals, weights)

    def joint_params(self, params: torch.Tensor, q0: torch.Tensor) -> torch.Tensor:
        """Parameters with absolute joint goals for a rollout starting at ``q0``."""
        params = params.float()
        if self.goal_frame == "absolute":
            return params
        out = params.clone()
        out[:, :7] = params[:, :7] + q0.float()
        return out

    def search_sigma(self) -> torch.Tensor:
        return self._sigma.clone()

    def bounded(self, traj: torch.Tensor, q0: torch.Tensor) -> torch.Tensor:
        """Joint trajectories (N, T, 7) kept inside the arm's limits and, with ``reach_bound`` =
        ``"path"``, inside ``q0 +- max_goal_offset`` at every step (the DMP bounds only the goal:
        its shape term can carry a joint 2-4 times farther on the way)."""
        b = self.dmp.max_goal_offset
        if self.reach_bound == "path" and b is not None:
            q0 = q0.to(traj.dtype)
            traj = torch.minimum(torch.maximum(traj, q0 - b), q0 + b)
        return self.world.kin.clamp(traj)

    def execute(self, params: torch.Tensor, state: State, watched: str | None) -> list[Result]:
        import time

        t0 = time.perf_counter()
        q0 = self._q(state)
        traj = self.bounded(self.dmp.rollout(self.joint_params(params, q0), q0, self.duration_s, self.dt), q0)
        fresh = state.q is None and state.toy_xy is None and state.toy_yaw is None
        self.world.start_state = None if fresh else (q0, state.toy_xy, state.toy_yaw)
        try:
            outs = self.world.rollout(traj, state.posture, watched=watched, use_filter=fresh)
        finally:
            self.world.start_state = None
        res = []
        for n, o in enumerate(outs):
            q_end = tuple(round(float(v), 6) for v in traj[n, o.stop_step])
            toy = tuple(round(float(v), 6) for v in o.final_toy_xy)
            yaw = round(float(o.final_toy_yaw), 6) if self.toy_turn == "keep" else 0.0
            res.append(Result(tuple(bool(e) for e in o.events), State(state.posture, q_end, toy, yaw or None),
                              o.fired_first))
        self.timing["rollout_s"] += time.perf_counter() - t0
        self.timing["rollouts"] += len(outs)
        return res

    def _observe(self, state: State) -> dict:
        """The eye's view of ``state`` (``ToolWorld.observe`` after setting the scene up)."""
        q = None if state.q is None else torch.tensor(state.q)
        return self.world.observe(posture=state.posture, q=q, toy_xy=state.toy_xy, toy_yaw=state.toy_yaw)

    def perceive(self, state: State) -> torch.Tensor:
        import time

        if state not in self._images:
            t0 = time.perf_counter()
            obs = self._observe(state)
            self._images[state] = torch.stack([obs["toy"], obs["rake"]]).to(torch.uint8)
            self.timing["render_s"] += time.perf_counter() - t0
            self.timing["renders"] += 1
        return self._images[state].float()

    def eye_image(self, state: State) -> np.ndarray:
        """The RGB image the eye sees in ``state`` (for figures)."""
        return self._observe(state)["image"]

    def _table_point(self, u: float, v: float) -> tuple[float, float]:
        """Where the ray through pixel (u, v) meets the plane of the toy's centre (world x, y)."""
        cfg, c = self.world.cfg, self.world.client
        if self._inv is None:
            eye, target, up = self.world.camera()
            view = np.array(c.computeViewMatrix(eye, target, up)).reshape(4, 4).T
            proj = np.array(c.computeProjectionMatrixFOV(cfg.camera_fov, cfg.image_width / cfg.image_height,
                                                         0.02, 3.0)).reshape(4, 4).T
            self._inv = np.linalg.inv(proj @ view)
        H, W = self.image_shape
        ndc = np.array([2 * (u + 0.5) / W - 1, 1 - 2 * (v + 0.5) / H])
        p0 = self._inv @ np.array([ndc[0], ndc[1], -1.0, 1.0])
        p1 = self._inv @ np.array([ndc[0], ndc[1], 1.0, 1.0])
        p0, p1 = p0[:3] / p0[3], p1[:3] / p1[3]
        z = cfg.table_top + cfg.toy_size / 2
        t = (z - p0[2]) / (p1[2] - p0[2])
        pt = p0 + t * (p1 - p0)
        return float(pt[0]), float(pt[1])

    def _toy_x(self, toy: torch.Tensor) -> float | None:
        """World x of the toy read from its colour map: the blob's centre projected onto the plane
        of the toy's centre (None if no toy is seen)."""
        m = float(toy.sum())
        if m < 1.0:
            return None
        cols, rows = toy.sum(0), toy.sum(1)  # the blob's centre from its two marginals
        u = float((torch.arange(len(cols), dtype=cols.dtype) * cols).sum()) / m
        v = float((torch.arange(len(rows), dtype=rows.dtype) * rows).sum()) / m
        return self._table_point(u, v)[0]

    def reader_bias(self) -> float:
        """Mean error (m) of :meth:`_toy_x` for a toy near the reachable area's border.

        The eye sees the toy's top and its near face, so the blob's centre lies a little beyond
        the toy's centre (about 1.4 mm here); a retrieving pull stops as soon as the toy's centre
        crosses the border, often less than that inside it. The bias is measured once, on the toy
        rendered alone at 15 known points within 4 mm of the border, and taken off every reading.
        """
        if self._bias is None:
            bx = self.world.cfg.retrieve_x
            errors = []
            for dx in (-0.004, -0.002, 0.0, 0.002, 0.004):
                for y in (-0.05, 0.0, 0.05):
                    toy = self.world.observe(posture=4, toy_xy=(bx + dx, y))["toy"]
                    errors.append(self._toy_x(torch.as_tensor(toy, dtype=torch.float32)) - (bx + dx))
            self._bias = float(np.mean(errors))
        return self._bias

    def reward(self, image: torch.Tensor) -> float:
        """1 if the toy, read from the image (blob centre projected back onto the table, less the
        reader's bias), lies in the reachable area."""
        x = self._toy_x(image[0])
        if x is None:
            return 0.0
        return 1.0 if x - self.reader_bias() < self.world.cfg.retrieve_x else 0.0


__all__ = ["EVENTS", "SKILL_LETTERS", "State", "Result", "Environment", "ToolUseBrain", "GatedHebbian",
           "AcquisitionConfig", "Skill", "Library", "acquire_skills", "build_brain", "Outcomes", "TrialRecord",
           "sequence_trial", "ToolWorldEnvironment"]
