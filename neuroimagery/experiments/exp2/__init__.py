"""Experiment 2 (thesis section 5.2): mental rotation through motor models, with wrist proprioception.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config

EXPERIMENT = Experiment(
    name="exp2",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report", "effects"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    min_objects=config.MIN_OBJECTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    memory_estimate=config.memory_estimate,
)
