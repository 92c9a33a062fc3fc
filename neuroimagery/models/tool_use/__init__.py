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
                    being first recognised as one of the initial situations practised in.
    C4  PC -> PMC   Q-learning (eq. 7.1, ``nn.rules.QLearning``), the standard sign.

Algorithms
    ``acquisition``  skill acquisition, Fig. 7.5 (exploration, PI^BB learning with the
                     competence stopping rule, training of C1, C2, C3).
    ``sequencing``   action sequencing, Fig. 7.6 (softmax over C1 + C4, a reactive child moves,
                     a planning child imagines the outcome through C3, Q-learning).
    ``skills``       a learnt primitive (``Skill``) and the real outcomes of sequences of
                     primitives (``Outcomes``, the rollout cache both share).

The model talks to the world through the small :class:`Environment` protocol (``common``), so the
same code runs on the pybullet rake-and-toy world (``robot.environment.ToolWorldEnvironment``) and
on cheap stand-ins in the tests.  Weight tensors live in buffers of :class:`ToolUseBrain` (one individual).

The names below are imported from their modules on first use, so that the parameters
(:mod:`.params`, read by Experiment 5's schema) are read without torch or the robot world.
"""
from __future__ import annotations

from ...core.imports import lazy_names

_WHERE = {  # name -> the module of this package (or of neuroimagery) that defines it
    **dict.fromkeys(("AcquisitionParams", "BrainParams", "SequencingParams"), ".params"),
    **dict.fromkeys(("Library", "acquire_skills", "build_brain"), ".acquisition"),
    **dict.fromkeys(("GatedHebbian", "ToolUseBrain"), ".brain"),
    **dict.fromkeys(("EVENTS", "N_POSTURES", "SKILL_LETTERS", "Environment", "Result", "State"), ".common"),
    **dict.fromkeys(("TrialRecord", "run_trial", "sequence_trial"), ".sequencing"),
    **dict.fromkeys(("Outcomes", "Skill"), ".skills"),
    "ToolWorldEnvironment": "neuroimagery.robot.environment",
}
__all__ = ["EVENTS", "SKILL_LETTERS", "N_POSTURES", "State", "Result", "Environment",
           "ToolUseBrain", "BrainParams", "GatedHebbian", "AcquisitionParams", "SequencingParams", "run_trial", "Skill", "Library", "acquire_skills", "build_brain",
           "Outcomes", "TrialRecord", "sequence_trial", "ToolWorldEnvironment"]

__getattr__ = lazy_names(__name__, _WHERE)
