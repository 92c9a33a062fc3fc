"""The parameters of the Experiment 3 model (``experiment.*`` of Experiment 3), apart from the model
(:mod:`neuroimagery.models.rotation_generalising`) so that the schema is read without torch."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field
from typing import List

from ..core.bounds import Rule, bounded, check_declared
from .params import ForwardModelParams, PostureMapParams, SelectionParams


@dataclass
class GeneralisingForwardModel(ForwardModelParams):
    """C6 (``experiment.fm``). PP_2 holds C6's output, the delta rule's actual output (eq. 6.4, linear:
    no threshold, no clipping; rule R6 of docs/choices.md), and the feedback PP_2 -> PP_1 passes it cut
    to [0, 1], the range of PP_1's units (rule R8)."""


@dataclass
class GeneralisingPostureParams(PostureMapParams):
    """C2/C3 (``experiment.posture``): their units' wrist postures and the graded code of eq. 6.5-6.6."""

    iterations: int = bounded(960, ge=1)  # supervised Kohonen steps (40 passes over 24 set-a images; not given)
    angles: List[float] = dc_field(default_factory=lambda: [45.0, 0.0, -45.0, -90.0])  # SS / PMC_1 units, decreasing
    code_sigma: float = bounded(0.15, gt=0)  # width of the Gaussian of eq. 6.5-6.6 on squared-distance differences (not given)

    RULES = (Rule("angles", lambda c: len(c.angles) >= 2 and list(c.angles) == sorted(c.angles, reverse=True),
                  "must be >= 2 decreasing angles"),)


@dataclass
class GeneralisingSelectionParams(SelectionParams):
    """M1_2's softmax (eq. 6.3) and the rotations before answering NO (``experiment.selection``)."""

    tau: float = bounded(0.3, gt=0)  # M1_2 softmax temperature (thesis 0.3)
    max_steps: int = bounded(15, ge=1)  # rotation steps before answering NO (thesis 15)


@dataclass
class GeneralisingParams:
    """The parameters of :class:`RotationGeneralising` (``experiment.*`` of Experiment 3)."""

    map_size: int = bounded(32, ge=1)  # side of V1, PP_1 (x3), PP_2, PFC_1, PFC_2 (thesis 32x32)
    step_deg: float = bounded(45.0, gt=0)  # rotation of one forward-model step (n1 -45, n3 +45)
    init_high: float = bounded(0.01, gt=0)  # initial weights U[0, init_high] (small random; not given)
    fm: GeneralisingForwardModel = dc_field(default_factory=GeneralisingForwardModel)  # C6 (delta rule, eq. 6.4)
    # C2/C3 (supervised Kohonen, eq. 6.7-6.8), their SS / PMC_1 units' postures and graded code (eq. 6.5-6.6)
    posture: GeneralisingPostureParams = dc_field(default_factory=GeneralisingPostureParams)
    # eq. 6.2 compares M1_1 with the weights of n1, n2, n3 by where the M1_1 activity is centred across the
    # diagonal (mean SS unit - PMC_1 unit, in posture units; contract X3.6), so that two flat posture codes,
    # like two coinciding ones, put it on the diagonal and select n2 (thesis 6.1.3: objects with no clear
    # orientation stop the rotation early).
    # width of the Gaussian of that read-out, in posture units (not given): half the spacing of the
    # posture units, so that a centre one unit off the diagonal selects a turn (n2 falls to ~0.3, the softmax
    # picks the turn ~87 % of the time) and a centre on the diagonal selects n2 (the turns fall to ~0.004)
    # (docs/choices.md, rule R7: combined with the spread of the M1_1 activity across the diagonal,
    # sqrt(sigma^2 + var), var the activity-weighted variance of (SS unit - PMC_1 unit), as a Gaussian-tuned
    # unit responds to a spread population input: a less certain code gives a less certain M1_2, 6.1.3)
    m1_centre_sigma: float = bounded(0.5, gt=0)
    # how far a PP_2 unit reaches when C8 subtracts it from PFC_2: 1 (default) = PP_2 read as a population code
    # whose units respond over their 3x3 neighbourhood (contract X3.8: an exact rotation of a same image leaves
    # <= 5 % of the target uncovered); 0 = the literal one-to-one reading, under which a resampled 45-deg
    # rotation of a 1-2-unit edge leaves about a quarter of the target uncovered.
    match_tolerance: int = bounded(1, ge=0)
    match_threshold: float = bounded(0.05, ge=0, le=1)  # NO when PMC_2 > this fraction of PFC_1's active units (thesis 5 %)
    # M1_2's softmax temperature (thesis 0.3) and the rotation steps before answering NO (thesis 15)
    selection: GeneralisingSelectionParams = dc_field(default_factory=GeneralisingSelectionParams)

    RULES = (Rule("fm.dot_inner", lambda c: c.fm.dot_inner <= c.map_size - 2, "must lie in [1, map_size - 2]",
                  show=False),)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)
