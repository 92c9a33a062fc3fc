"""The parameters of the Experiment 1 model (``experiment.*`` of Experiment 1), apart from the model
(:mod:`neuroimagery.models.rotation_affordance`) so that the schema is read without torch."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field

from ..core.bounds import Rule, bounded, check_declared
from .params import FieldParams, SomParams


@dataclass
class AffordanceParams:
    """The parameters of :class:`AffordanceRotationModel` (``experiment.*`` of Experiment 1)."""

    step_deg: float = bounded(15.0, gt=0)  # rotation of one C1/C2 cycle and spacing of the trained orientations (thesis: 15)
    max_cycles: int = bounded(10, ge=1)  # rotation cycles before the model gives up and matches the last image (thesis: 10)
    centre_tolerance_deg: float = bounded(7.5, gt=0)  # |posture| at which the PMC_1 cluster counts as "at the centre" (half a step)
    init_high: float = bounded(0.1, gt=0)  # initial weights U[0, init_high] (thesis: 0.1)
    hebb_eta: float = bounded(0.3, gt=0, le=1)  # outstar Hebbian rate of C1, C2, C5 (not given in the thesis)
    hebb_epochs: int = bounded(6, ge=1)  # passes over the training patterns (Table 5.1 of Exp. 2 uses 6 passes)
    posture_sigma_deg: float = bounded(6.0, gt=0)  # width of a PMC_1 posture cluster (deg along both axes)
    object_band_deg: float = bounded(22.5, ge=0)  # PMC_1 row offset (deg units) of object A (-) and B (+) clusters
    answer_sigma: float = bounded(1.5, gt=0)  # width (units) of the PMC_2 answer clusters
    image_threshold: float = bounded(0.5, gt=0, lt=1)  # C2 output (max-normalised) above which a PC unit is on in the mental image
    sharpen: float = bounded(4.0, gt=0)  # exponent on the PMC_1 column profile before the competition (contrast)
    som: SomParams = dc_field(default_factory=SomParams)  # the PFC_2 map (not given for Exp. 1) and its cluster
    field: FieldParams = dc_field(default_factory=FieldParams)  # the PMC_1 and PMC_2 competitions

    RULES = (Rule("step_deg", lambda c: 90 % c.step_deg == 0, "must divide 90"),)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)
