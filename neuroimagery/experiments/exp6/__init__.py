"""Experiment 6 (beyond the thesis): mental rotation of Shepard-Metzler objects in three dimensions. The protocol: :mod:`.protocol`."""
from ...core.experiment import Experiment
from . import protocol

EXPERIMENT = Experiment(
    name="exp6",
    config=protocol.CONFIG,
    train=protocol.train,
    load=protocol.load,
    evaluate=protocol.evaluate,
    report=protocol.report,
    checkpoints=protocol.CHECKPOINTS,
    inputs=protocol.INPUTS,
    runtime_keys=protocol.RUNTIME_KEYS,
    test_keys=protocol.TEST_KEYS,
    memory_estimate=protocol.memory_estimate,
    check_inputs=protocol.check_inputs,
    ineffective_keys=protocol.ineffective_keys,
    effects=protocol.effects,
)
