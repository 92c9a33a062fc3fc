"""Experiment 5 (thesis chapter 7): tool-use development in infant robots.

The schema and what the checks before any work read: :mod:`.config` (nothing heavy imported); the
phases: :mod:`.protocol`, imported when one first runs."""
import functools

from ...core.experiment import Experiment, lazy
from . import config
from .checks import check_inputs

_phase = functools.partial(lazy, f"{__name__}.protocol")  # a function of the protocol, imported on first call

EXPERIMENT = Experiment(
    name="exp5",
    config=config.CONFIG,
    train=_phase("train"),
    load=_phase("load"),
    evaluate=_phase("evaluate"),
    report=_phase("report"),
    checkpoints=config.CHECKPOINTS,
    inputs=config.INPUTS,
    runtime_keys=config.RUNTIME_KEYS,
    test_keys=config.TEST_KEYS,
    check_inputs=check_inputs,
    ineffective_keys=config.ineffective_keys,
    trained_count=_phase("trained_count"),
    pool_runs=_phase("pool_runs"),
    pool_free_keys=config.POOL_FREE_KEYS,
    pool_rows=config.POOL_ROWS,
)
