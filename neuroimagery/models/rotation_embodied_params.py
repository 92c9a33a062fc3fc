"""The parameters of the Experiment 4 model (``experiment.*`` of Experiment 4): maps, forward
models, posture maps, action selection, decision and embodiment."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field
from typing import List, Optional

from .params import ForwardModelParams, PostureMapParams


@dataclass
class EmbodiedPostureParams(PostureMapParams):
    """C16/C17 (``experiment.posture``) and how PPCp reads its winner."""

    # PPCp winner of the mental image (eq. 6.14): 0 = arg-max of the C16 potentials; > 0 = drawn from a
    # softmax of the max-normalised potentials at this temperature (uncertain for unfamiliar shapes,
    # whose potentials are nearly flat). 0.1 = the PMCm temperature, not fitted. PPCt stays arg-max.
    tau: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.tau < 0:
            raise ValueError(f"experiment.posture.tau must be >= 0, got {self.tau!r}")


@dataclass
class EmbodiedParams:
    """The parameters of :class:`RotationEmbodied` (``experiment.*`` of Experiment 4)."""

    # --- maps and stimuli -------------------------------------------------------------
    map_size: int = 32  # side of every image map (Table 6.1: 32x32)
    step_deg: float = 30.0  # rotation of one forward-model step (POCl +30, POCr -30)
    ppc_angles: List[float] = dc_field(default_factory=lambda: [-60.0, -30.0, 0.0, 30.0, 60.0, 90.0])  # wrist posture of each PPCp/PPCt unit, increasing
    # --- forward models C1-C3 (delta rule, eq. 6.4) -------------------------------------
    init_high: float = 0.01  # initial weights U[0, init_high] of every trained connection ("small random"; not given)
    fm: ForwardModelParams = dc_field(default_factory=ForwardModelParams)
    # --- posture maps C16/C17 (supervised Kohonen, eq. 6.14-6.16) and the PPCp winner -----
    posture: EmbodiedPostureParams = dc_field(default_factory=EmbodiedPostureParams)
    # axis of the flipped target PFCft (C10, "flipped along the main object axis of the object"; not given how):
    # 'ppct' (default: the higher IoU with the true mirror on training set A, the rule of docs/contracts.md) =
    # the axis of the orientation PPCt reads (C17), so a misread target posture also gives a wrong flip |
    # 'image' = the principal axis of the target map itself (no posture input). No label either way.
    flip_axis: str = "ppct"
    # how far a POCp unit reaches when PFCtm / PFCfm compare it with the target (C8, C9): 1 (default) = POCp read
    # as a population code whose units respond over their 3x3 neighbourhood (contract X4.7); 0 = one-to-one
    match_tolerance: int = 1
    ppc_sigma: float = 0.5  # width (units) of the Gaussian bump PPCp/PPCt put around the winner (eq. 6.14; not given)
    # --- action selection (eq. 6.10-6.11) ---------------------------------------------------
    softmax_tau: float = 0.1  # PMCm softmax temperature (thesis 0.1)
    # --- decision (PMCd, eq. 6.12-6.13) ----------------------------------------------------
    lca_k: float = 0.5  # leak k (not given in the thesis)
    lca_w: float = 0.5  # mutual inhibition w (C15, thesis 0.5)
    lca_threshold: float = 1.2  # decision threshold (thesis 1.2)
    lca_dt: float = 0.1  # Euler step per cycle (not given)
    lca_cycles: int = 10  # accumulator cycles per rotation step (thesis 10)
    # input scale: evidence = gain * |PFCxm| / |PFCt| (C13/C14 weights of 1.0 over the overlap, per target
    # unit); None = the rule of docs/choices.md: the smallest gain with which a full overlap crosses the
    # threshold within one step (1.495 with k 0.5, dt 0.1, 10 cycles)
    lca_input_gain: Optional[float] = None
    # the rule that sets the gain when lca_input_gain is null: 'identical' (default; contract X4.9) = the
    # smallest gain with which the mean evidence (target and flipped overlap) of identical 0-deg pairs of the
    # training set decides YES within one step, per participant, fixed after training | 'full' = the smallest
    # gain with which a full overlap (1, with no flipped overlap) does (lca_gain)
    lca_gain_rule: str = "identical"
    max_steps: int = 20  # rotation steps before a random answer (thesis 20)
    # --- embodiment -----------------------------------------------------------------------
    proprio_gain: float = 1.0  # strength of the wrist signal added to PPCp (scaled encoder signal; not given)
    # where the wrist signal joins PPCp (not given): 'separate' = added after the noisy image-derived
    # bump is clipped to [0, 1] (the encoder is an input of its own, untouched by the noise that stands
    # for an unreliable image-to-posture mapping); 'visual' = summed with the bump before noise and clip,
    # so on the congruent unit it saturates at 1 and cannot outweigh the noise on the other units
    proprio_stage: str = "visual"
    noise_amplitude: float = 0.5  # noise variant: U[-a, a] added to each PPCp unit per step (thesis 0.5)
    # --- protocol size ----------------------------------------------------------------------

    def __post_init__(self) -> None:
        def pos(k, strict=True):
            v = getattr(self, k)
            if not (v > 0 if strict else v >= 0):
                raise ValueError(f"experiment.{k} must be {'>' if strict else '>='} 0, got {v!r}")
        for k in ("step_deg", "init_high", "ppc_sigma", "softmax_tau",
                  "lca_threshold", "lca_dt"):
            pos(k)
        for k in ("lca_k", "lca_w", "proprio_gain", "noise_amplitude"):
            pos(k, strict=False)
        for k in ("map_size", "lca_cycles", "max_steps"):
            if int(getattr(self, k)) < 1:
                raise ValueError(f"experiment.{k} must be >= 1, got {getattr(self, k)!r}")
        if self.map_size < 8:
            raise ValueError(f"experiment.map_size must be >= 8, got {self.map_size}")
        if not (1 <= self.fm.dot_inner <= self.map_size - 2):
            raise ValueError(f"experiment.fm.dot_inner must lie in [1, map_size - 2], got {self.fm.dot_inner}")
        from ..nn.decision import LeakyCompetingAccumulator
        from ..nn.functional import check_bounds

        lca = ("k", "w", "threshold", "dt")  # within the bounds the accumulator enforces (one source)
        check_bounds({k: LeakyCompetingAccumulator.BOUNDS[k] for k in lca}, {k: getattr(self, f"lca_{k}") for k in lca},
                     {k: f"experiment.lca_{k}" for k in lca})
        if len(self.ppc_angles) < 2 or list(self.ppc_angles) != sorted(self.ppc_angles):
            raise ValueError(f"experiment.ppc_angles must be >= 2 increasing angles, got {list(self.ppc_angles)}")
        if self.flip_axis not in ("image", "ppct"):
            raise ValueError(f"experiment.flip_axis must be 'image' or 'ppct', got {self.flip_axis!r}")
        if self.lca_input_gain is not None and not self.lca_input_gain > 0:
            raise ValueError(f"experiment.lca_input_gain must be > 0 (or null for the rule), got {self.lca_input_gain!r}")
        if self.lca_gain_rule not in ("identical", "full"):
            raise ValueError(f"experiment.lca_gain_rule must be 'identical' or 'full', got {self.lca_gain_rule!r}")
        if int(self.match_tolerance) < 0:
            raise ValueError(f"experiment.match_tolerance must be >= 0, got {self.match_tolerance!r}")
        if self.proprio_stage not in ("separate", "visual"):
            raise ValueError(f"experiment.proprio_stage must be 'separate' or 'visual', got {self.proprio_stage!r}")
