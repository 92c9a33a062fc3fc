"""Experiment 3 (thesis section 6.1): mental rotation with generalising forward models. The protocol: :mod:`.protocol`."""
from ...core.experiment import Experiment
from . import protocol

EXPERIMENT = Experiment(
    name="exp3",
    config=protocol.CONFIG,
    train=protocol.train,
    load=protocol.load,
    evaluate=protocol.evaluate,
    report=protocol.report,
    checkpoints=protocol.CHECKPOINTS,
    inputs=protocol.INPUTS,
    test_keys=protocol.TEST_KEYS,
    memory_estimate=protocol.memory_estimate,
    check_inputs=protocol.check_inputs,
    ineffective_keys=protocol.ineffective_keys,
    effects=protocol.effects,
)
