"""Parameter groups the models of Experiments 1-4 and 6 share, each a typed dataclass that an
experiment's configuration nests under one key (``experiment.field``, ``experiment.som``,
``experiment.fm``, ``experiment.posture``, ``experiment.selection``, ``experiment.lca``,
``experiment.ppc``). A key that means the same in two experiments lives in the same group under
the same name. A model reads only its own groups; the range checks are declared on the fields
(:mod:`neuroimagery.core.bounds`) and run when the group is built, naming the key where it lives."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ..core.bounds import bounded, check_declared


# ------------------------------------------------------------------ chapter 5 (Exp 1-2)
@dataclass
class FieldParams:
    """The dynamic fields (``nn.DynamicField``) that pick a posture or an answer (``experiment.field``)."""

    tau: float = bounded(10.0, gt=0)  # time constant (cycles)
    h: float = -0.2  # resting level
    a_exc: float = bounded(0.5, ge=0)  # local excitation amplitude
    sigma_exc: float = bounded(2.0, gt=0)  # local excitation width (units)
    a_inh: float = bounded(0.05, ge=0)  # global inhibition
    threshold: float = bounded(0.9, gt=0)  # activity that ends a competition
    gain: float = bounded(1.0, gt=0)  # input gain into a field
    max_cycles: int = bounded(500, ge=1)  # cycles before a competition is cut off

    KEYS = ("tau", "h", "a_exc", "sigma_exc", "a_inh", "threshold")  # the DynamicField's own arguments

    def __post_init__(self) -> None:
        check_declared(self, "experiment.field.")
        from ..nn.limits import FIELD_BOUNDS, check_bounds  # the bounds of nn.decision.DynamicField

        check_bounds(FIELD_BOUNDS, self.field_kwargs(), {k: f"experiment.field.{k}" for k in self.KEYS})

    def field_kwargs(self) -> dict:
        """The keyword arguments of ``DynamicField``."""
        return {k: getattr(self, k) for k in self.KEYS}


@dataclass
class SomParams:
    """An unsupervised Kohonen map of chapter 5 (eq. 4.5; ``experiment.som``) and the cluster the
    model keeps around its winner."""

    iterations: int = bounded(2000, ge=1)  # online training steps
    eta: float = bounded(0.1, gt=0, le=1)  # initial rate
    eta_final: float = bounded(0.01, gt=0)  # final rate
    sigma: float = bounded(8.0, gt=0)  # initial neighbourhood radius (grid units)
    sigma_final: float = bounded(0.5, gt=0)  # final radius
    cutoff: float = bounded(1e-6, ge=0, lt=1)  # the Gaussian neighbourhood is cut to 0 below this fraction of the winner's update
    # implementation of the online rule (the forms of nn.som_*, registered in nn.forms): 'windowed' (per-participant window), 'factored'
    # or 'online'; the same winners, other costs
    method: str = bounded("windowed", choices=("windowed", "factored", "online"))
    threads: int = bounded(1, ge=1)  # intra-op threads while a map trains (each step is small: threads only add hand-offs)
    cluster_sigma: float = bounded(2.0, gt=0)  # width of the cluster around the winner passed on to the next connections

    def __post_init__(self) -> None:
        check_declared(self, "experiment.som.")

    def som_kwargs(self) -> dict:
        """The schedule arguments of ``nn.SOM``."""
        return dict(eta=self.eta, eta_final=self.eta_final, sigma=self.sigma, sigma_final=self.sigma_final,
                    iterations=self.iterations)


# ------------------------------------------------------------------ chapter 6 (Exp 3-4)
@dataclass
class ForwardModelParams:
    """The three-dot forward models trained by the delta rule (eq. 6.4; ``experiment.fm``)."""

    eta: float = bounded(0.1, gt=0)  # delta-rule rate (thesis 0.1)
    images: int = bounded(4000, ge=1)  # three-dot training images per participant (not given)
    batch: int = bounded(8, ge=1)  # images per delta-rule update (changes summed at the same weights); 1 = purely online
    dot_inner: int = bounded(23, ge=1)  # dots lie in the central inner x inner square (thesis 23)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.fm.")


@dataclass
class PostureMapParams:
    """The image -> wrist-posture maps (supervised Kohonen, eq. 6.7-6.8 / 6.14-6.16;
    ``experiment.posture``)."""

    eta: float = bounded(0.1, gt=0)  # Kohonen rate (thesis 0.1)
    # rate at the last step: = eta, the thesis's constant 0.1; lower = an exponential decay
    # (e.g. 0.002: each prototype ends as an average of its images)
    eta_final: float = bounded(0.1, gt=0)
    sigma: float = bounded(0.3, gt=0)  # neighbourhood radius of the forced winner, in units (not given)
    iterations: int = bounded(1440, ge=1)  # supervised Kohonen steps (not given)
    # The image reaches the rule and the read-out divided by its sum (the scale of the weights eq. 6.8 / 6.16
    # keep at sum 1, so eta is the real rate), and the training images come in passes, every image once per
    # pass in a fresh random order ("repeated for all the possible orientations"): docs/choices.md.

    def __post_init__(self) -> None:
        check_declared(self, "experiment.posture.")


@dataclass
class SelectionParams:
    """How the next move is chosen and for how long (``experiment.selection``; Exp 3, 4 and 6): a
    softmax over the move units (eq. 6.3 / 6.11), and the moves made before the answer is given
    without a match."""

    tau: float = bounded(0.1, gt=0)  # softmax temperature (thesis 0.1 in Exp 4)
    max_steps: int = bounded(20, ge=1)  # rotation steps before the answer is given without a match (thesis 20 in Exp 4)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.selection.")


@dataclass
class LcaParams:
    """PMCd, the leaky competing accumulator that decides YES / NO (eq. 6.12-6.13;
    ``experiment.lca``; Exp 4 and 6). ``k``, ``w``, ``threshold`` and ``dt`` lie within the bounds
    the accumulator itself declares (``nn.LeakyCompetingAccumulator.BOUNDS``, one source)."""

    k: float = 0.5  # leak (not given in the thesis)
    w: float = 0.5  # mutual inhibition (C15, thesis 0.5)
    threshold: float = 1.2  # decision threshold (thesis 1.2)
    dt: float = 0.1  # Euler step per cycle (not given)
    cycles: int = bounded(10, ge=1)  # accumulator cycles per rotation step (thesis 10)
    # input scale: evidence = gain * the match; None = the experiment's rule (docs/choices.md)
    input_gain: Optional[float] = bounded(None, gt=0)

    KEYS = ("k", "w", "threshold", "dt")  # the accumulator's own arguments

    def __post_init__(self) -> None:
        from ..nn.limits import LCA_BOUNDS, check_bounds  # the bounds of nn.decision.LeakyCompetingAccumulator

        check_bounds({k: LCA_BOUNDS[k] for k in self.KEYS},
                     {k: getattr(self, k) for k in self.KEYS}, {k: f"experiment.lca.{k}" for k in self.KEYS})
        check_declared(self, "experiment.lca.")


@dataclass
class PpcParams:
    """PPCp / PPCt, the wrist-posture population (eq. 6.14; ``experiment.ppc``; Exp 4 and 6): the
    bump around the posture read from an image, and the wrist signal added to PPCp."""

    sigma: float = bounded(0.5, gt=0)  # width (units) of the Gaussian bump around the winner (not given)
    proprio_gain: float = bounded(1.0, ge=0)  # strength of the wrist signal added to PPCp (scaled encoder signal; not given)

    def __post_init__(self) -> None:
        check_declared(self, "experiment.ppc.")
