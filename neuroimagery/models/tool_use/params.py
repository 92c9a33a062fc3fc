"""The parameters of the tool-use model (``experiment.acquisition``, ``experiment.brain`` and
``experiment.sequencing`` of Experiment 5), apart from the model so that the schema is read
without torch."""
from __future__ import annotations

from dataclasses import dataclass

from ...core.bounds import bounded, check_declared
from ...robot.events import EVENTS


@dataclass
class AcquisitionParams:
    """Parameters of skill acquisition, Fig. 7.5 (``experiment.acquisition`` of Exp 5). The
    exploration noise the world draws (its DMP goals and weights) is the world's
    (``experiment.world``)."""

    n_dmps: int = bounded(10, ge=len(EVENTS), why="one primitive per event")  # M1 / PMC units, the free DMPs (thesis: 10)
    pibb_samples: int = bounded(10, ge=2)  # K samples per posture and update (thesis: 10)
    pibb_temperature: float = bounded(0.1, gt=0)  # tau of eq. 7.7 on the 0/1 costs (not given)
    pibb_decay: float = bounded(0.9, gt=0, le=1)  # exploration covariance factor per PI^BB update (not given)
    max_epochs: int = bounded(10, ge=1)  # PI^BB epochs at most (thesis: 10)
    competence_tolerance: float = bounded(0.05, ge=0, le=1)  # stop when the competence changes by less (thesis: 0.05)
    c1_repeats: int = bounded(10, ge=0)  # C1 updates per PI^BB update (thesis: 10)
    c2_repeats: int = bounded(10, ge=0)  # C2 updates per successful competence check (thesis: 10)
    c3_repeats: int = bounded(50, ge=0)  # C3 updates per successful competence check (thesis: 50)
    hip_threshold: float = bounded(0.5, ge=0, le=1)  # a distal goal (C2 -> HIP) this active makes an event "not new"
    explore_batch: int = bounded(8, ge=1)  # exploration movements rolled out per batch (the first new event wins)
    explore_max_rollouts: int = bounded(400, ge=1)  # give up looking for further events after this many movements
    # rollouts of one DMP without a new event before it is given back with fresh random
    # parameters (one PI^BB epoch's worth: 4 postures x 10 samples; docs/exp5.md)
    explore_patience: int = bounded(40, ge=1)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.acquisition.")


@dataclass
class BrainParams:
    """The learning rates and read-outs of C1-C4 (``experiment.brain`` of Exp 5)."""

    c1_eta: float = bounded(0.1, gt=0, le=1)  # C1 Hebbian rate (not given)
    c2_eta: float = bounded(0.1, gt=0, le=1)  # C2 Hebbian rate (not given)
    c3_eta: float = bounded(0.1, gt=0, le=1)  # C3 SOM rate (not given); 50 steps make the prototype the last outcome
    c3_sigma: float = bounded(0.1, gt=0)  # C3 neighbourhood width in units; small: each pair keeps its own unit
    c3_action_gain: float = bounded(100.0, gt=0)  # weight of the primitive's code against the image in C3's input
    eta: float = bounded(1e-4, gt=0, le=1)  # C4 Q-learning rate (thesis: 0.0001) on the 2 x 240 x 320 binary PC map
    gamma: float = bounded(0.8, ge=0, le=1)  # discount (thesis: 0.8)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.brain.")


@dataclass
class SequencingParams:
    """Parameters of action sequencing, Fig. 7.6 (``experiment.sequencing`` of Exp 5)."""

    attempts: int = bounded(5, ge=1)  # primitives per trial (thesis: 5)
    temperature: float = bounded(0.1, gt=0)  # softmax temperature of action selection in training trials (not given)
    test_temperature: float = bounded(0.1, gt=0)  # softmax temperature in the test trial (not given)
    # Fig. 7.6 "select one active neuron of PMC": a unit is active when its PMC activity (C1 + C4)
    # is above this; 0 = above the maps' resting level (the default, docs/exp5.md). A child with
    # no active unit does not move.
    active_threshold: float = bounded(0.0, ge=0, lt=1)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.sequencing.")
