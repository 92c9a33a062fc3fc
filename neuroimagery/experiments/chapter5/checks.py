"""Memory estimate of Experiments 1, 2 and the demo before any work (``neuroimagery.core.resources``).

Their maps have fixed sides, so a run's size is set by ``participants``: the weights of one
participant (Exp 2: about 230 MB, Exp 1: about 45 MB) times their number. The bytes of one
participant are read from a one-participant model (its parameters and buffers), built only when
the run asks for more participants than the default (10), so a run of the usual size pays nothing.
"""
from __future__ import annotations

from ...core.experiment import lazy
from ...core.resources import Need, human

DEFAULT_PARTICIPANTS = 10


def weights_estimate(cfg, model_cls) -> list[Need]:
    """``participants`` times the bytes of one participant of ``model_cls(e, participants, seed)``."""
    P = int(cfg.participants)
    if P <= DEFAULT_PARTICIPANTS:
        return []
    import torch

    with torch.no_grad():
        one = model_cls(cfg.experiment, 1, cfg.seed)
    each = sum(t.numel() * t.element_size() for t in (*one.parameters(), *one.buffers()))
    return [Need(f"participants={P}", float(each) * P, f"weights, {P} x {human(each)} per participant")]


def weights_of(module: str, model: str):
    """The ``memory_estimate(cfg)`` of an experiment whose size is its weights: :func:`weights_estimate`
    with the class ``model`` of ``module``, imported only when a run asks for more participants
    than the default."""

    def memory_estimate(cfg) -> list[Need]:
        return weights_estimate(cfg, lazy(module, model))

    return memory_estimate
