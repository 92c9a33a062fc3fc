"""Building blocks: population-coded maps, connections, local learning rules, SOMs and decision
dynamics. No block knows which experiment uses it.

The forms of the rules are registered where they are defined; :mod:`.forms` loads those modules
itself before its first lookup. The names below are imported from their modules on first use, so
that a light module of the package (:mod:`.limits`, the bounds the schemas check with) is read
without torch."""
from __future__ import annotations

from ..core.imports import lazy_names

_WHERE = {  # name -> the module of this package that defines it
    **dict.fromkeys(("AllToAll", "Connection", "GainField", "HardWired", "OneToOne"), ".connections"),
    **dict.fromkeys(("Decision", "DynamicField", "LeakyCompetingAccumulator"), ".decision"),
    "Delta": ".delta",
    **dict.fromkeys(("gain_field", "gaussian_bump", "softmax_probabilities", "softmax_select", "transfer"), ".functional"),
    **dict.fromkeys(("PopulationMap", "population_cover"), ".maps"),
    **dict.fromkeys(("GatedHebbian", "Hebbian", "Kohonen", "QLearning", "Rule", "Sanger", "SupervisedKohonen"), ".rules"),
    "participant_generators": ".seeding",
    **dict.fromkeys(("SOM", "BidirectionalSOM"), ".som"),
}
__all__ = [
    "AllToAll", "Connection", "GainField", "HardWired", "OneToOne",
    "Decision", "DynamicField", "LeakyCompetingAccumulator",
    "gain_field", "gaussian_bump", "softmax_probabilities", "softmax_select", "transfer",
    "PopulationMap", "population_cover", "Delta", "GatedHebbian", "Hebbian", "Kohonen", "QLearning", "Rule", "Sanger", "SupervisedKohonen",
    "participant_generators", "SOM", "BidirectionalSOM",
]

__getattr__ = lazy_names(__name__, _WHERE)
