"""Experiment 1's schema (``experiment.*``) and what the checks before any work read of it
(:mod:`neuroimagery.validation`, :mod:`neuroimagery.core.manifest`): nothing heavy is imported here."""
from __future__ import annotations

from dataclasses import dataclass, field

from ...core.bounds import bounded, check_declared
from ...models.rotation_affordance_params import AffordanceParams
from ..chapter5.checks import weights_of


@dataclass
class Exp1Quick:
    """What ``preset=quick`` shrinks (``experiment.quick``)."""

    # the rule of docs/choices.md ("Quick presets"): the full protocol's training, a quarter of its participants
    som_iterations: int = bounded(2000, ge=1)  # PFC_2's SOM steps (at most som.iterations): the full protocol's
    participants: int = bounded(3, ge=1)  # a run tests the smaller of `participants` and this

    def __post_init__(self) -> None:
        check_declared(self, "experiment.quick.")


@dataclass
class Exp1Config(AffordanceParams):
    """The model's parameters (:class:`AffordanceParams`) and the run's."""

    name: str = "exp1"
    quick: Exp1Quick = field(default_factory=Exp1Quick)  # what preset=quick shrinks
    auto_threads: int = bounded(0, ge=0)  # intra-op threads for training and testing when the run's `threads` is 0; 0: the free cores measured at start (see docs)


CONFIG = Exp1Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ("vision", "stimuli")
MIN_OBJECTS = 2  # a user folder must hold a shape and its mirror
CHECKPOINTS = ("model",)
RUNTIME_KEYS = ("som.threads", "auto_threads")  # thread counts: speed only
TEST_KEYS = ()  # the model is built from every key, so each one counts as a training setting

memory_estimate = weights_of("neuroimagery.models.rotation_affordance", "AffordanceRotationModel")  # the weights of every participant
