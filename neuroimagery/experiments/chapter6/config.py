"""The configuration groups Experiments 3 and 4 share (``experiment.quick``, ``experiment.percept``):
read by the checks before any work, so nothing heavy is imported here."""
from __future__ import annotations

from dataclasses import dataclass

from ...core.bounds import bounded, check_declared


@dataclass
class QuickParams:
    """What ``preset=quick`` shrinks in Experiments 3 and 4 (``experiment.quick``)."""

    objects: int = bounded(1, ge=1)  # objects per test set
    fm_images: int = bounded(3000, ge=1)  # three-dot training images

    def __post_init__(self) -> None:
        check_declared(self, "experiment.quick.")


@dataclass
class PerceptParams:
    """How the percept varies between looks (``experiment.percept``; docs/choices.md, rule R4): each
    look at an object is off by a gaze error of ``gaze_error_deg`` (sd, pan and tilt each; one step of
    the iCub's 12-bit joint encoders), the view sampled at the sub-pixel offset; each test builds ``looks`` looks per item from its own stream
    and each trial takes one look at each of its objects. 0 looks: every trial sees one fixed image."""

    looks: int = bounded(16, ge=0)  # looks per item built for each test (0 = one fixed image per item)
    gaze_error_deg: float = bounded(360.0 / 4096, ge=0, le=5)  # sd of the gaze error per look, deg

    def __post_init__(self) -> None:
        check_declared(self, "experiment.percept.")
