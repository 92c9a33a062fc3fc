"""Experiment 5 (thesis chapter 7): tool-use development in infant robots. The protocol: :mod:`.protocol`."""
from ...core.experiment import Experiment
from . import protocol

EXPERIMENT = Experiment(
    name="exp5",
    config=protocol.CONFIG,
    train=protocol.train,
    load=protocol.load,
    evaluate=protocol.evaluate,
    report=protocol.report,
    checkpoints=protocol.CHECKPOINTS,
    inputs=protocol.INPUTS,
    runtime_keys=protocol.RUNTIME_KEYS,
    test_keys=protocol.TEST_KEYS,
    check_inputs=protocol.check_inputs,
    ineffective_keys=protocol.ineffective_keys,
    trained_count=protocol.trained_count,
    pool_runs=protocol.pool_runs,
    pool_free_keys=protocol.POOL_FREE_KEYS,
)
