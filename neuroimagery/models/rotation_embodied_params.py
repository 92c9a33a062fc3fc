"""The parameters of the Experiment 4 model (``experiment.*`` of Experiment 4): maps, forward
models, posture maps, action selection, decision and embodiment. The groups ``selection``,
``lca`` and ``ppc`` are shared with Experiment 6 (and ``selection`` with Experiment 3)
(:mod:`neuroimagery.models.params`); every range check is declared (:mod:`neuroimagery.core.bounds`)."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field
from typing import List

from ..core.bounds import Rule, bounded, check_declared
from .params import ForwardModelParams, LcaParams, PostureMapParams, PpcParams, SelectionParams

PROPRIOCEPTION = ("none", "match", "mismatch")  # the wrist conditions


@dataclass
class EmbodiedPostureParams(PostureMapParams):
    """C16/C17 (``experiment.posture``) and how PPCp reads its winner."""

    # PPCp winner of the mental image (eq. 6.14): 0 = arg-max of the C16 potentials; > 0 = drawn from a
    # softmax of the max-normalised potentials at this temperature (uncertain for unfamiliar shapes,
    # whose potentials are nearly flat). 0.1 = the PMCm temperature, not fitted. PPCt stays arg-max.
    tau: float = bounded(0.0, ge=0)


@dataclass
class EmbodiedLcaParams(LcaParams):
    """PMCd (``experiment.lca``).

    ``input_gain``: evidence = gain * |PFCxm| / |PFCt| (C13/C14 weights of 1.0 over the overlap, per
    target unit). When it is null (the default) the gain is set by rule R1 of docs/choices.md: per
    participant, after training, the smallest gain with which at least 90 % of the identical 0-deg
    pairs of the training set (each image against itself) decide (for the unit their evidence
    favours) within one step. The leak is set by rule R2, ``k`` being its lowest value: per
    participant, after training, the smallest k on a grid of 0.05 from w to w + 2.5 with which at
    most 10 % of the misaligned same-object pairs of the training set (object and angle only, no
    appearance or answer label) decide when held for ``selection.max_steps`` steps (the gain by R1
    at each k)."""


@dataclass
class EmbodiedPpcParams(PpcParams):
    """PPCp / PPCt (``experiment.ppc``): the units' wrist postures, the bump, the wrist signal and
    the noise variant."""

    angles: List[float] = dc_field(default_factory=lambda: [-60.0, -30.0, 0.0, 30.0, 60.0, 90.0])  # wrist posture of each unit, increasing
    # the wrist signal is summed with the image-derived bump before noise and clip (docs/choices.md), so on
    # the congruent unit it saturates at 1 and cannot outweigh the noise on the other units
    noise_amplitude: float = bounded(0.5, ge=0)  # noise variant: U[-a, a] added to each PPCp unit per step (thesis 0.5)

    RULES = (Rule("angles", lambda c: len(c.angles) >= 2 and list(c.angles) == sorted(c.angles),
                  "must be >= 2 increasing angles"),)


@dataclass
class EmbodiedParams:
    """The parameters of :class:`RotationEmbodied` (``experiment.*`` of Experiment 4)."""

    # --- maps and stimuli -------------------------------------------------------------
    map_size: int = bounded(32, ge=8)  # side of every image map (Table 6.1: 32x32)
    step_deg: float = bounded(30.0, gt=0)  # rotation of one forward-model step (POCl +30, POCr -30)
    # --- forward models C1-C3 (delta rule, eq. 6.4) -------------------------------------
    init_high: float = bounded(0.01, gt=0)  # initial weights U[0, init_high] of every trained connection ("small random"; not given)
    fm: ForwardModelParams = dc_field(default_factory=ForwardModelParams)
    # --- posture maps C16/C17 (supervised Kohonen, eq. 6.14-6.16) and the PPCp winner -----
    posture: EmbodiedPostureParams = dc_field(default_factory=EmbodiedPostureParams)
    # --- PPCp / PPCt: postures, bump, wrist signal, noise (eq. 6.14) -----------------------
    ppc: EmbodiedPpcParams = dc_field(default_factory=EmbodiedPpcParams)
    # the flipped target PFCft (C10, "flipped along the main object axis of the object"; not given how) is the
    # target reflected about the axis of the orientation PPCt reads (C17; docs/choices.md), so a misread target
    # posture also gives a wrong flip. No label is read.
    # how far a POCp unit reaches when PFCtm / PFCfm compare it with the target (C8, C9): 1 (default) = POCp read
    # as a population code whose units respond over their 3x3 neighbourhood (contract X4.7); 0 = one-to-one
    match_tolerance: int = bounded(1, ge=0)
    # --- action selection (PMCm, eq. 6.10-6.11) and decision (PMCd, eq. 6.12-6.13) ----------
    selection: SelectionParams = dc_field(default_factory=SelectionParams)  # softmax (thesis 0.1), steps (thesis 20)
    # PMCm's input AM (eq. 6.10) reaches the softmax of eq. 6.11 divided by one constant (docs/choices.md,
    # rule R3): the total activity PPCc holds when PPCt and PPCp are the eq. 6.14 bump on the same most central
    # unit (the largest total the bumps give), the same for every trial
    lca: EmbodiedLcaParams = dc_field(default_factory=EmbodiedLcaParams)

    RULES = (Rule("fm.dot_inner", lambda c: c.fm.dot_inner <= c.map_size - 2, "must lie in [1, map_size - 2]",
                  show=False),)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.", recursive=False)
