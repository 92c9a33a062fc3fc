"""The parameters of the Experiment 2 model (``experiment.*`` of Experiment 2), apart from the model
(:mod:`neuroimagery.models.rotation_motor`) so that the schema is read without torch."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field

from ..core.bounds import bounded, check_declared
from .params import FieldParams, SomParams


@dataclass
class MotorRotationParams:
    """The parameters of :class:`MotorRotationModel` (``experiment.*`` of Experiment 2)."""

    max_cycles: int = bounded(10, ge=1)  # rotation cycles before matching the last image (thesis: 10)
    init_high: float = bounded(0.1, gt=0)  # initial weights U[0, init_high] (thesis: 0.1)
    hebb_eta: float = bounded(0.3, gt=0, le=1)  # outstar Hebbian rate of every Hebbian connection (not given)
    c1_epochs: int = bounded(6, ge=1)  # passes over the 14 images for C1 and C6 (Table 5.1: 84 cycles = 6 x 14)
    # babbling steps that train C9, C10 and C2, after the SOM M1_1 has finished (Table 5.1: 1,960 for C9 and
    # C10; it gives C2 14 patterns x 84 cycles, here C2 learns on these same steps; see docs/exp2.md)
    hebb_steps: int = bounded(1960, ge=1)
    c5_epochs: int = bounded(6, ge=1)  # passes over the 196 pairs for C5 (Table 5.1: 1,176 = 6 x 196)
    # the SOMs M1_1 and PFC_2 (Table 5.1: 10,000 steps; radius not given, see docs/exp2.md) and the
    # winning cluster they pass on to C5, C9, C10
    som: SomParams = dc_field(default_factory=lambda: SomParams(iterations=10000, cutoff=0.01, cluster_sigma=1.0))
    posture_sigma_deg: float = bounded(6.0, gt=0)  # width of SS / PMC_1 posture clusters (deg)
    object_band_deg: float = bounded(22.5, ge=0)  # SS row offset of object A (-) and B (+)
    preactivation: float = bounded(0.2, gt=0)  # C1 pre-activation of each afforded posture (thesis: 0.2)
    bias: float = bounded(1.0, gt=0)  # C6 bias of the selected posture (thesis: 1.0)
    proprio_gain: float = bounded(0.5, ge=0, lt=1, why="weaker than the forward model")  # input to SS, forward model = 1
    answer_sigma: float = bounded(1.5, gt=0)  # width of PMC_2 / M1_2 clusters (units)
    image_threshold: float = bounded(0.5, gt=0, lt=1)  # C2 output (max-normalised) above which a PP unit is on
    # the SS and PMC_2 competitions (inhibition strong enough that the weaker proprioceptive cluster alone cannot win)
    field: FieldParams = dc_field(default_factory=lambda: FieldParams(a_inh=0.2))

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)
