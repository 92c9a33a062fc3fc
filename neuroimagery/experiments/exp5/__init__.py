"""Experiment 5 (thesis chapter 7): tool-use development in infant robots.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
from ...core.experiment import Experiment, phases
from . import config
from .checks import check_inputs

EXPERIMENT = Experiment(
    name="exp5",
    config=config.CONFIG,
    **phases(__name__, "train", "load", "evaluate", "report", "trained_count", "pool_runs"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    check_inputs=check_inputs,
    ineffective_keys=config.ineffective_keys,
    pool_free_keys=config.POOL_FREE_KEYS,
    pool_rows=config.POOL_ROWS,
)
