"""Parameter groups the models of Experiments 1-4 share, each a typed dataclass that an
experiment's configuration nests under one key (``experiment.field``, ``experiment.som``,
``experiment.fm``, ``experiment.posture``). A model reads only its own groups; the range checks
run when the group is built and name the key where it lives."""
from __future__ import annotations

from dataclasses import dataclass


def _check(group: str, obj, positive=(), at_least_one=(), non_negative=()) -> None:
    for k in positive:
        if not getattr(obj, k) > 0:
            raise ValueError(f"experiment.{group}.{k} must be > 0, got {getattr(obj, k)!r}")
    for k in at_least_one:
        if getattr(obj, k) < 1:
            raise ValueError(f"experiment.{group}.{k} must be >= 1, got {getattr(obj, k)!r}")
    for k in non_negative:
        if getattr(obj, k) < 0:
            raise ValueError(f"experiment.{group}.{k} must be >= 0, got {getattr(obj, k)!r}")


# ------------------------------------------------------------------ chapter 5 (Exp 1-2)
@dataclass
class FieldParams:
    """The dynamic fields (``nn.DynamicField``) that pick a posture or an answer (``experiment.field``)."""

    tau: float = 10.0  # time constant (cycles)
    h: float = -0.2  # resting level
    a_exc: float = 0.5  # local excitation amplitude
    sigma_exc: float = 2.0  # local excitation width (units)
    a_inh: float = 0.05  # global inhibition
    threshold: float = 0.9  # activity that ends a competition
    gain: float = 1.0  # input gain into a field
    max_cycles: int = 500  # cycles before a competition is cut off

    KEYS = ("tau", "h", "a_exc", "sigma_exc", "a_inh", "threshold")  # the DynamicField's own arguments

    def __post_init__(self) -> None:
        _check("field", self, positive=("tau", "sigma_exc", "threshold", "gain"), at_least_one=("max_cycles",),
               non_negative=("a_exc", "a_inh"))
        from ..nn.decision import DynamicField
        from ..nn.functional import check_bounds

        check_bounds(DynamicField.BOUNDS, self.field_kwargs(), {k: f"experiment.field.{k}" for k in self.KEYS})

    def field_kwargs(self) -> dict:
        """The keyword arguments of ``DynamicField``."""
        return {k: getattr(self, k) for k in self.KEYS}


@dataclass
class SomParams:
    """An unsupervised Kohonen map of chapter 5 (eq. 4.5; ``experiment.som``) and the cluster the
    model keeps around its winner."""

    iterations: int = 2000  # online training steps
    eta: float = 0.1  # initial rate
    eta_final: float = 0.01  # final rate
    sigma: float = 8.0  # initial neighbourhood radius (grid units)
    sigma_final: float = 0.5  # final radius
    cutoff: float = 1e-6  # the Gaussian neighbourhood is cut to 0 below this fraction of the winner's update
    # implementation of the online rule (nn.som_trainers): 'windowed' (per-participant window), 'factored'
    # or 'online'; the same winners, other costs
    method: str = "windowed"
    threads: int = 1  # intra-op threads while a map trains (each step is small: threads only add hand-offs)
    cluster_sigma: float = 2.0  # width of the cluster around the winner passed on to the next connections

    def __post_init__(self) -> None:
        _check("som", self, positive=("eta", "eta_final", "sigma", "sigma_final", "cluster_sigma"),
               at_least_one=("iterations", "threads"))
        if self.eta > 1:
            raise ValueError(f"experiment.som.eta must be <= 1, got {self.eta!r}")
        if not 0 <= self.cutoff < 1:
            raise ValueError(f"experiment.som.cutoff must be in [0, 1), got {self.cutoff!r}")
        if self.method not in ("windowed", "factored", "online"):
            raise ValueError(f"experiment.som.method must be 'windowed', 'factored' or 'online', got {self.method!r}")

    def som_kwargs(self) -> dict:
        """The schedule arguments of ``nn.SOM``."""
        return dict(eta=self.eta, eta_final=self.eta_final, sigma=self.sigma, sigma_final=self.sigma_final,
                    iterations=self.iterations)


# ------------------------------------------------------------------ chapter 6 (Exp 3-4)
@dataclass
class ForwardModelParams:
    """The three-dot forward models trained by the delta rule (eq. 6.4; ``experiment.fm``)."""

    eta: float = 0.1  # delta-rule rate (thesis 0.1)
    images: int = 4000  # three-dot training images per participant (not given)
    batch: int = 8  # images per delta-rule update (changes summed at the same weights); 1 = purely online
    dot_inner: int = 23  # dots lie in the central inner x inner square (thesis 23)

    def __post_init__(self) -> None:
        _check("fm", self, positive=("eta",), at_least_one=("images", "batch", "dot_inner"))


@dataclass
class PostureMapParams:
    """The image -> wrist-posture maps (supervised Kohonen, eq. 6.7-6.8 / 6.14-6.16;
    ``experiment.posture``)."""

    eta: float = 0.1  # Kohonen rate (thesis 0.1)
    # rate at the last step: = eta, the thesis's constant 0.1; lower = an exponential decay
    # (e.g. 0.002: each prototype ends as an average of its images)
    eta_final: float = 0.1
    sigma: float = 0.3  # neighbourhood radius of the forced winner, in units (not given)
    iterations: int = 1440  # supervised Kohonen steps (not given)
    # scale of the image fed to the rule and the read-out (not given): 'sum' = divided by its sum, the scale of
    # the weights eq. 6.8 / 6.16 keep at sum 1, so eta is the real rate | 'raw' = the binary map as it comes
    input_scale: str = "sum"
    # order of the training images (not given; "repeated for all the possible orientations"): 'passes' = every
    # image once per pass, in a fresh random order each pass | 'draws' = each step draws an image at random
    order: str = "passes"

    def __post_init__(self) -> None:
        _check("posture", self, positive=("eta", "eta_final", "sigma"), at_least_one=("iterations",))
        if self.input_scale not in ("sum", "raw"):
            raise ValueError(f"experiment.posture.input_scale must be 'sum' or 'raw', got {self.input_scale!r}")
        if self.order not in ("passes", "draws"):
            raise ValueError(f"experiment.posture.order must be 'passes' or 'draws', got {self.order!r}")


def moved_keys(groups: dict[str, tuple[str, type]]) -> dict[str, str]:
    """``{old flat key: new dotted key}`` for groups ``{group: (old prefix, dataclass)}``: e.g.
    ``field_tau`` -> ``field.tau``. Old names that do not follow the prefix are added by the caller."""
    import dataclasses

    out = {}
    for group, (prefix, cls) in groups.items():
        for f in dataclasses.fields(cls):
            out[f"{prefix}{f.name}"] = f"{group}.{f.name}"
    return out
