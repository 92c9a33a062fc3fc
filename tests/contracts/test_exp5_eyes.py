"""Experiment 5 contract W12 (docs/contracts.md): one pair of eyes in action sequencing. Both
children take the reward from the next camera image through the same reader; the simulator's
retrieve detector is only the analysis's record of a real retrieval."""
from __future__ import annotations

import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from support_tool_env import StandInToolEnv  # noqa: E402

from neuroimagery.models.tool_use import (AcquisitionParams, Outcomes, ToolUseBrain, acquire_skills,  # noqa: E402
                                          build_brain, sequence_trial)


class BlindEnv(StandInToolEnv):
    """The stand-in world whose reader never sees the toy in reach (its retrieve detector still fires)."""

    def reward(self, image):
        return 0.0


def test_w12_the_reactive_child_judges_from_the_image_not_the_detector():
    acq = AcquisitionParams(max_epochs=3, explore_max_rollouts=200, c1_repeats=3, c2_repeats=3, c3_repeats=5)
    env = StandInToolEnv()
    lib = acquire_skills(env, ["retrieve", "touch", "west"], acq, torch.Generator().manual_seed(2))
    for cls, sees in ((StandInToolEnv, True), (BlindEnv, False)):
        e = cls()
        brain = build_brain(e, lib, acq, ToolUseBrain(e.image_shape), torch.Generator().manual_seed(0))
        outcomes = Outcomes(e, {s.name: s for s in lib.skills}, e.perceive)
        g = torch.Generator().manual_seed(3)
        recs = [sequence_trial(brain, outcomes, lib.skills, 1, "reactive", False, 5, 0.1, g) for _ in range(6)]
        for rec in recs:
            for n, reward in enumerate(rec.rewards):
                x1 = outcomes.image(1, tuple(rec.actions[:n + 1]))
                assert reward == float(e.reward(x1))  # the reader on the next image, nothing else
        assert any(rec.success for rec in recs)  # the toy really came in (analysis) ...
        if not sees:  # ... but a child whose eyes never show it keeps trying: no reward, all attempts
            assert all(not any(rec.rewards) and len(rec.actions) == 5 for rec in recs)
