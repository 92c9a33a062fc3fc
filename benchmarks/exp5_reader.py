"""How often the eye's reader (robot.eye.ToyReader, the reward of both children in Exp 5) agrees
with the simulator's retrieve detector on scenes that moved the toy.

    python benchmarks/exp5_reader.py

Exploration movements (seed 11) from postures 1 (twice), 2 and 4, 200 each, stopped at retrieve
(posture 4: at retrieve or west); every scene in which an event fired is rendered and read.
Prints the reader's bias and the table (detector, reader) -> count.
"""
import torch

from neuroimagery.experiments.exp5.config import WorldParams
from neuroimagery.robot.environment import ToolWorldEnvironment

w = WorldParams()
env = ToolWorldEnvironment(w.world_config(), **w.env_kwargs())
g = torch.Generator().manual_seed(11)
tab = {(a, b): 0 for a in (0, 1) for b in (0, 1)}
for p in (1, 1, 2, 4):
    for _ in range(5):
        theta = env.explore_params(env.random_primitive(g), p, 40, g)
        for r in env.execute(theta, env.start(p), "retrieve" if p != 4 else ("retrieve", "west")):
            if not any(r.events):
                continue
            seen = int(env.reward(env.perceive(r.next_state)) > 0)
            tab[(int(r.retrieved), seen)] += 1
print("reader bias (m)", round(env.reader_bias(), 4))
print("(detector, reader): count", tab)
env.close()
