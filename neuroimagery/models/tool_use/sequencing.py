"""Action sequencing (thesis Fig. 7.6): a child chooses primitives by softmax over C1 + C4, a
reactive child performs them, a planning child imagines their outcome through C3, and C4 learns
by Q-learning (eq. 7.1)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import torch

from ...nn.functional import softmax_select
from .brain import ToolUseBrain
from ...bounds import bounded, check_declared
from .common import CHOICES, check_choice
from .skills import Outcomes, Skill


@dataclass
class SequencingParams:
    """Parameters of action sequencing, Fig. 7.6 (``experiment.sequencing`` of Exp 5)."""

    attempts: int = bounded(5, ge=1)  # primitives per trial (thesis: 5)
    temperature: float = bounded(0.1, gt=0)  # softmax temperature of action selection in training trials (not given)
    test_temperature: float = bounded(0.1, gt=0)  # softmax temperature in the test trial (not given)
    # how a planning child is tested (Fig. 7.6 does not say): 'act' = each attempt chooses from the
    # real scene with the C4 learnt in mind, imagines, performs and looks again | 'plan' = the whole
    # plan is made in mind from the initial image, then performed. See docs/exp5.md.
    planning_test: str = bounded("act", choices=CHOICES["planning_test"])
    # Fig. 7.6 "select one active neuron of PMC": a unit is active when its PMC activity (C1 + C4)
    # is above this; 0 = above the maps' resting level (the default, docs/exp5.md). A child with
    # no active unit does not move.
    active_threshold: float = bounded(0.0, ge=0, lt=1)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.sequencing.")


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
                   record_frames: bool = False, planning_test: str = "act",
                   active_threshold: float = 0.0) -> TrialRecord:
    """One trial of Fig. 7.6 from initial posture ``posture``.

    Each attempt: feed the current PC image through C1 and C4, pick one acquired PMC unit with
    softmax (among the active ones, ``active_threshold``), then a reactive child performs the
    primitive (the real scene is perceived next) while a planning child imagines it through C3
    (the mental image becomes the next input). The toy-related reward is read from that next
    image by the environment's reader (``env.reward``), the same for both children; the
    simulator's retrieve detector only says, for the analysis, whether the toy was really
    retrieved (``TrialRecord.success``). In training mode C4 learns by eq. 7.1; a planning
    child trains in mind only.

    The test (``training`` False) of a planning child, ``planning_test``:

    * ``"act"``: every attempt starts from the real scene: the child chooses from what it sees
      (C1 + the C4 it learnt in mind), imagines the outcome, performs the primitive and looks
      again; it stops once the toy is really in reach.
    * ``"plan"``: the whole plan (up to ``attempts`` primitives, until the mental image shows the
      toy in reach) is made in mind from the initial image, then performed for real.

    Test success is always the real retrieval.

    ``active_threshold``: Fig. 7.6 draws among the *active* PMC units: the acquired units whose
    PMC activity (C1 + C4) is above it (0: above the maps' resting level); a child with no active
    unit does not move (the trial ends).
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
            # one pair of eyes (Fig. 7.6, lines 1585-1586; docs/contracts.md W12): the reward is read
            # from the next camera image by the same reader the planning child uses on its mental image
            r = outcomes.after(posture, done_events)
            x1 = outcomes.perceive(r.next_state)
            reward = float(env.reward(x1))
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
        # analysis only: whether the toy is really in reach after the child's last move (the
        # simulator's retrieve detector; the child itself judged from its eyes)
        rec.success = bool(done_events) and outcomes.after(posture, done_events).retrieved
    else:
        rec.imagined_success = bool(rec.rewards and rec.rewards[-1] > 0)
        # "plan" test: the plan is performed for real (prefixes are cached); stop once the toy is in reach
        for n in range(1, 0 if training else len(rec.actions) + 1):
            if outcomes.after(posture, tuple(rec.actions[:n])).retrieved:
                rec.success = True
                break
    brain.eval()
    return rec


def run_trial(brain: ToolUseBrain, outcomes: Outcomes, skills: Sequence[Skill], posture: int, strategy: str,
              training: bool, params: SequencingParams, generator: torch.Generator,
              record_frames: bool = False) -> TrialRecord:
    """:func:`sequence_trial` with the settings of ``params`` (the test temperature in a test)."""
    return sequence_trial(brain, outcomes, skills, posture, strategy, training, params.attempts,
                          params.temperature if training else params.test_temperature, generator,
                          record_frames=record_frames, planning_test=params.planning_test,
                          active_threshold=params.active_threshold)
