"""The bounds of the blocks' parameters and their checks, in plain Python: the schemas
(:mod:`neuroimagery.models.params`) check a configuration with the bounds the blocks declare
without importing torch."""
from __future__ import annotations

import math

# the parameters of nn.decision.DynamicField and nn.decision.LeakyCompetingAccumulator (keyword
# arguments of check_rate); the blocks and the schemas check with these
FIELD_BOUNDS = {"tau": dict(low=1.0), "h": dict(low=-math.inf), "a_exc": {}, "sigma_exc": dict(open_low=True),
                "a_inh": {}, "threshold": dict(open_low=True)}
LCA_BOUNDS = {"k": {}, "w": {}, "threshold": dict(open_low=True), "dt": dict(open_low=True, high=1.0), "noise": {}}


def check_rate(name: str, value: float, low: float = 0.0, high: float | None = None, open_low: bool = False) -> float:
    """Raise ValueError naming ``name`` unless ``low <= value (<= high)`` and finite."""
    v = float(value)
    if not math.isfinite(v) or v < low or (open_low and v == low) or (high is not None and v > high):
        rng = f"({low}, {high}]" if open_low else f"[{low}, {'inf' if high is None else high}]"
        raise ValueError(f"{name} must be in {rng}, got {value!r}")
    return v


def check_bounds(bounds: dict, values: dict, names: dict | None = None) -> dict:
    """:func:`check_rate` of each of ``values`` with its entry of ``bounds`` (keyword arguments of
    :func:`check_rate`); an error names ``names[key]`` (e.g. the config key a block's parameter
    comes from), so a schema and the block it feeds share one set of bounds."""
    names = names or {}
    out = {}
    for key, value in values.items():
        try:
            out[key] = check_rate(names.get(key, key), value, **bounds[key])
        except TypeError:
            raise ValueError(f"{names.get(key, key)} must be a number, got {value!r}") from None
    return out
