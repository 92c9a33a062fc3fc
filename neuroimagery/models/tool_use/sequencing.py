"""Action sequencing (thesis Fig. 7.6): a child chooses primitives by softmax over C1 + C4, a
reactive child performs them, a planning child imagines their outcome through C3, and C4 learns
by Q-learning (eq. 7.1)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import torch

from ...nn.functional import softmax_select
from .brain import ToolUseBrain
from .params import SequencingParams
from .skills import Outcomes, Skill


@dataclass
class TrialRecord:
    """One action-sequencing trial (Fig. 7.6)."""

    actions: list[str]
    rewards: list[float]
    success: bool  # the toy was really retrieved
    imagined_success: bool = False  # planning: the plan reached the goal in mind
    frames: list[dict] = field(default_factory=list)  # optional film strip (real / imagined PC)


def sequence_trial(brain: ToolUseBrain, outcomes: Outcomes, skills: Sequence[Skill], posture: int, strategy: str,
                   training: bool, attempts: int, temperature: float, generator: torch.Generator,
                   record_frames: bool = False, active_threshold: float = 0.0) -> TrialRecord:
    """One trial of Fig. 7.6 from initial posture ``posture``.

    Each attempt: feed the current PC image through C1 and C4, pick one acquired PMC unit with
    softmax (among the active ones, ``active_threshold``), then a reactive child performs the
    primitive (the real scene is perceived next) while a planning child imagines it through C3
    (the mental image becomes the next input). The toy-related reward is read from that next
    image by the environment's reader (``env.reward``), the same for both children; the
    simulator's retrieve detector only says, for the analysis, whether the toy was really
    retrieved (``TrialRecord.success``). In training mode C4 learns by eq. 7.1; a planning
    child trains in mind only.

    In the test (``training`` False) every attempt of a planning child starts from the real scene
    (Fig. 7.6 "get visual input as x0"): the child chooses from what it sees (C1 + the C4 it learnt
    in mind), imagines the outcome, performs the primitive and looks again; it stops once the toy
    is really in reach. Test success is always the real retrieval.

    ``active_threshold``: Fig. 7.6 draws among the *active* PMC units: the acquired units whose
    PMC activity (C1 + C4) is above it (0: above the maps' resting level); a child with no active
    unit does not move (the trial ends).
    """
    if strategy not in ("reactive", "planning"):
        raise ValueError(f"strategy must be 'reactive' or 'planning', got {strategy!r}")
    units = torch.tensor([s.unit for s in skills])
    by_unit = {s.unit: s for s in skills}
    done_events: tuple[str, ...] = ()
    x0 = outcomes.image(posture, ())
    rec = TrialRecord([], [], False)
    if len(skills) == 0:
        return rec
    brain.train(training)
    child = _Child(brain, outcomes, posture, acting=strategy == "reactive" or not training,
                   imagining=strategy == "planning", record_frames=record_frames)
    for _ in range(attempts):
        skill = _choose(brain, x0, units, by_unit, active_threshold, temperature, generator)
        if skill is None:
            break  # nothing afforded here: the child does not move
        done_events = done_events + (skill.name,)
        x1, reward = child.perform(x0, skill, done_events, rec)
        if training:
            brain.q_update(x0, skill.unit, reward, x1, done=reward > 0)
        x0 = x1
        if reward > 0:
            break
    child.score(rec, done_events)
    brain.eval()
    return rec


def _choose(brain: ToolUseBrain, x0: torch.Tensor, units: torch.Tensor, by_unit: dict[int, Skill],
            active_threshold: float, temperature: float, generator: torch.Generator) -> Skill | None:
    """The skill whose PMC unit softmax picks among the active ones (activity from image ``x0``
    above ``active_threshold``); None when no unit is active."""
    act = brain.pmc(x0)[units]
    active = act > active_threshold
    if not bool(active.any()):
        return None
    act = act.masked_fill(~active, float("-inf"))
    k = int(softmax_select(act.view(1, -1), temperature, generators=[generator])[0])
    return by_unit[int(units[k])]


@dataclass
class _Child:
    """How a child of a trial from ``posture`` moves: ``acting`` performs each primitive and looks
    again, ``imagining`` imagines its outcome through C3 (both in a planning child's test)."""

    brain: ToolUseBrain
    outcomes: Outcomes
    posture: int
    acting: bool
    imagining: bool
    record_frames: bool

    def perform(self, x0: torch.Tensor, skill: Skill, done_events: tuple[str, ...], rec: TrialRecord
                ) -> tuple[torch.Tensor, float]:
        """One primitive, ``skill``, from image ``x0`` (``done_events`` the primitives so far, this one
        last), recorded in ``rec``. Returns the next image (seen or imagined) and the reward read from it."""
        env = self.outcomes.env
        imagined = self.brain.imagine(x0, skill.unit) if self.imagining or self.record_frames else None
        if self.imagining and float(env.reward(imagined)) > 0:
            rec.imagined_success = True
        if self.acting:
            # one pair of eyes (Fig. 7.6, lines 1585-1586; docs/contracts.md W12): the reward is read
            # from the next camera image by the same reader the planning child uses on its mental image
            r = self.outcomes.after(self.posture, done_events)
            x1 = self.outcomes.perceive(r.next_state)
        else:
            x1 = imagined
        reward = float(env.reward(x1))
        rec.actions.append(skill.name)
        rec.rewards.append(reward)
        if self.record_frames:
            rec.frames.append({"action": skill.name, "real": self.outcomes.image(self.posture, done_events),
                               "imagined": imagined, "reward": reward})
        return x1, reward

    def score(self, rec: TrialRecord, done_events: tuple[str, ...]) -> None:
        """``rec.success``: whether the toy is really retrieved after the trial (and, for a child
        that only imagined, ``rec.imagined_success`` from its last mental image)."""
        if self.acting:
            # analysis only: whether the toy is really in reach after the child's last move (the
            # simulator's retrieve detector; the child itself judged from its eyes)
            rec.success = bool(done_events) and self.outcomes.after(self.posture, done_events).retrieved
            return
        rec.imagined_success = bool(rec.rewards and rec.rewards[-1] > 0)


def run_trial(brain: ToolUseBrain, outcomes: Outcomes, skills: Sequence[Skill], posture: int, strategy: str,
              training: bool, params: SequencingParams, generator: torch.Generator,
              record_frames: bool = False) -> TrialRecord:
    """:func:`sequence_trial` with the settings of ``params`` (the test temperature in a test)."""
    return sequence_trial(brain, outcomes, skills, posture, strategy, training, params.attempts,
                          params.temperature if training else params.test_temperature, generator,
                          record_frames=record_frames, active_threshold=params.active_threshold)
