"""Experiment 1 (thesis section 5.1): mental rotation from affordances and a forward model.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
import functools

from ...core.experiment import Experiment, lazy
from . import config

_phase = functools.partial(lazy, f"{__name__}.protocol")  # a function of the protocol, imported on first call

EXPERIMENT = Experiment(
    name="exp1",
    config=config.CONFIG,
    train=_phase("train"),
    load=_phase("load"),
    evaluate=_phase("evaluate"),
    report=_phase("report"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    min_objects=config.MIN_OBJECTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    memory_estimate=config.memory_estimate,
    effects=_phase("effects"),
)
