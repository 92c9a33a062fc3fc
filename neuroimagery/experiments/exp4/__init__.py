"""Experiment 4 (thesis section 6.2): generalisation, decision making and embodiment in mental rotation.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config
from ..chapter6.checks import check_inputs, memory_estimate

EXPERIMENT = Experiment(
    name="exp4",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report", "effects"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    test_keys=config.TEST_KEYS,
    memory_estimate=memory_estimate,
    check_inputs=check_inputs,
    ineffective_keys=config.ineffective_keys,
)
