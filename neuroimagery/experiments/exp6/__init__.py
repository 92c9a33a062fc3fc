"""Experiment 6 (beyond the thesis): mental rotation of Shepard-Metzler objects in three dimensions.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config
from .checks import check_inputs, memory_estimate

EXPERIMENT = Experiment(
    name="exp6",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report", "effects"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    memory_estimate=memory_estimate,
    check_inputs=check_inputs,
    ineffective_keys=config.ineffective_keys,
)
