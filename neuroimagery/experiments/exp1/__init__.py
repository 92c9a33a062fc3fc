"""Experiment 1 (thesis section 5.1): mental rotation from affordances and a forward model. The protocol: :mod:`.protocol`."""
from ...core.experiment import Experiment
from . import protocol

EXPERIMENT = Experiment(
    name="exp1",
    config=protocol.CONFIG,
    train=protocol.train,
    load=protocol.load,
    evaluate=protocol.evaluate,
    report=protocol.report,
    checkpoints=protocol.CHECKPOINTS,
    inputs=protocol.INPUTS,
    min_objects=protocol.MIN_OBJECTS,
    runtime_keys=protocol.RUNTIME_KEYS,
    test_keys=protocol.TEST_KEYS,
    memory_estimate=protocol.memory_estimate,
    effects=protocol.effects,
)
