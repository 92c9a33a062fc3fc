"""A small demonstration built from the blocks alone: mental rotation of a population-coded angle. The protocol: :mod:`.protocol`."""
from ...core.experiment import Experiment
from . import protocol

EXPERIMENT = Experiment(
    name="demo",
    config=protocol.CONFIG,
    train=protocol.train,
    load=protocol.load,
    evaluate=protocol.evaluate,
    report=protocol.report,
    checkpoints=protocol.CHECKPOINTS,
    inputs=protocol.INPUTS,
    test_keys=protocol.TEST_KEYS,
    memory_estimate=protocol.memory_estimate,
)
