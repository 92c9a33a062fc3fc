"""neuroimagery: neurorobotic models of mental imagery (mental rotation and tool use) on a
simulated iCub, built from population-coded maps with local learning rules in PyTorch."""

__version__ = "0.2.0"
