"""A small demonstration built from the blocks alone: mental rotation of a population-coded angle.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config

EXPERIMENT = Experiment(
    name="demo",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    test_keys=config.TEST_KEYS,
    memory_estimate=config.memory_estimate,
)
