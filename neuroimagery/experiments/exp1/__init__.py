"""Experiment 1 (thesis section 5.1): mental rotation from affordances and a forward model.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config

EXPERIMENT = Experiment(
    name="exp1",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report", "effects"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    min_objects=config.MIN_OBJECTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    memory_estimate=config.memory_estimate,
)
