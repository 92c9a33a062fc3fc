"""The demo's schema (``experiment.*``) and what the checks before any work read of it
(:mod:`neuroimagery.validation`, :mod:`neuroimagery.core.manifest`): nothing heavy is imported here."""
from __future__ import annotations

from dataclasses import dataclass

from ...core.bounds import bounded, check_declared
from ..chapter5.checks import weights_of


@dataclass
class DemoConfig:
    name: str = "demo"
    step_deg: float = bounded(15.0, gt=0)  # rotation produced by one affordance -> forward cycle
    units: int = bounded(37, ge=1)  # ANGLE and POSTURE map sizes (5 deg resolution over -90..90)
    sigma_deg: float = bounded(8.0, gt=0)  # tuning width of both maps
    eta: float = bounded(0.2, gt=0)  # Hebbian learning rate
    epochs: int = bounded(30, ge=1)  # passes over the training angles
    max_steps: int = bounded(10, ge=1)  # rotation cycles before giving up
    cycles_per_step: int = bounded(10, ge=1)  # simulated ms per rotation cycle
    noise: float = bounded(0.05, ge=0)  # activity noise added to the angle code per step (eq. 4.1 n_i)
    sharpen: float = bounded(4.0, gt=0)  # exponent applied to the max-normalised forward-model output

    def __post_init__(self) -> None:
        check_declared(self, "experiment.")


CONFIG = DemoConfig

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ()
CHECKPOINTS = ("model",)
TEST_KEYS = ("max_steps", "cycles_per_step", "noise", "sharpen")  # read by the test only

memory_estimate = weights_of("neuroimagery.models.angle_rotation", "AngleRotationModel")  # the weights of every participant
