"""Building blocks: population-coded maps, connections, local learning rules, SOMs and decision
dynamics. No block knows which experiment uses it.

The forms of the rules are registered where they are defined; :mod:`.forms` loads those modules
itself before its first lookup."""
from .connections import AllToAll, Connection, GainField, HardWired, OneToOne
from .decision import Decision, DynamicField, LeakyCompetingAccumulator
from .delta import Delta
from .functional import gain_field, gaussian_bump, softmax_probabilities, softmax_select, transfer
from .maps import PopulationMap, population_cover
from .rules import GatedHebbian, Hebbian, Kohonen, QLearning, Rule, Sanger, SupervisedKohonen
from .seeding import participant_generators
from .som import SOM, BidirectionalSOM

__all__ = [
    "AllToAll", "Connection", "GainField", "HardWired", "OneToOne",
    "Decision", "DynamicField", "LeakyCompetingAccumulator",
    "gain_field", "gaussian_bump", "softmax_probabilities", "softmax_select", "transfer",
    "PopulationMap", "population_cover", "Delta", "GatedHebbian", "Hebbian", "Kohonen", "QLearning", "Rule", "Sanger", "SupervisedKohonen",
    "participant_generators", "SOM", "BidirectionalSOM",
]
