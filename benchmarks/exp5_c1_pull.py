"""C1's output for the pull in situation 4 against situation 1, per robot (docs/exp5.md).

    python benchmarks/exp5_c1_pull.py --seed 0 --repetitions 30 [--situation far]

C1 (Fig. 7.4) is the Hebbian PC -> PMC affordance: after skill acquisition (Fig. 7.5) a PMC unit's
output for a scene is the mean C1 weight over the scene's active PC units
(``ToolUseBrain.affordance``). Each robot here is the six-detector robot of one repetition of
``experiment=exp5`` (the library HP2's robots and HP1's 22-month group share), acquired exactly as
``exp5.run_task`` does (same generators, same brain seed); no model change. For each robot: the
pull's C1 output in situation 1 (tool behind the toy) and 4 (tool far), the largest C1 output of
any other acquired skill in each, and whether the pull is C1's strongest unit in situation 4.
The toy's part of the image is the same in all four situations; only the rake differs.
"""
from __future__ import annotations

import argparse
import copy
import statistics
import time

import torch

from neuroimagery.experiments.exp5.task import _gen, _task_environment
from neuroimagery.experiments.exp5.config import SITUATIONS, Exp5Config
from neuroimagery.models.tool_use import EVENTS, ToolUseBrain, acquire_skills


def robot(e, env, fresh, seed: int, r: int, situation: str) -> dict:
    sit_id = list(SITUATIONS).index(situation)
    mask = sum(1 << EVENTS.index(x) for x in EVENTS)
    brain = copy.deepcopy(fresh)
    lib = acquire_skills(env, list(EVENTS), e.acquisition, _gen(seed, 1, r, sit_id, mask), brain=brain)
    pulls = [s for s in lib.skills if s.event == "retrieve"]
    row = dict(seed=seed, repetition=r, situation=situation, skills=len(lib.skills), pull=bool(pulls))
    if not pulls:
        return row
    pull = pulls[0]
    others = [s.unit for s in lib.skills if s is not pull]
    for p in (1, 4):
        c1 = brain.affordance(env.perceive(env.start(p)))
        row[f"pull_{p}"] = float(c1[pull.unit])
        row[f"other_max_{p}"] = float(c1[others].max()) if others else 0.0
    row["pull_top_in_4"] = row["pull_4"] > row["other_max_4"]
    row["pull_succeeds_from"] = [p for p in range(1, 5) if pull.succeeds_from[p - 1]]
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, nargs="+", default=[0])
    parser.add_argument("--repetitions", type=int, default=30)
    parser.add_argument("--situation", choices=tuple(SITUATIONS), default="far")
    args = parser.parse_args()
    torch.set_num_threads(1)
    e = Exp5Config()
    env = _task_environment(e)
    rows = []
    c0 = time.process_time()
    print("| seed | robot | pull's C1, situation 1 | situation 4 | 4 / 1 | strongest other, 1 | 4 | pull strongest in 4 | pull succeeds from |\n"
          "|---|---|---|---|---|---|---|---|---|", flush=True)
    for seed in args.seed:
        fresh = ToolUseBrain.from_params(env.image_shape, e.brain, n_dmps=e.acquisition.n_dmps, seed=seed)
        for r in range(args.repetitions):
            row = robot(e, env, fresh, seed, r, args.situation)
            rows.append(row)
            if row["pull"]:
                print(f"| {seed} | {r} | {row['pull_1']:.3f} | {row['pull_4']:.3f} | {row['pull_4'] / max(row['pull_1'], 1e-9):.2f} "
                      f"| {row['other_max_1']:.3f} | {row['other_max_4']:.3f} | {'yes' if row['pull_top_in_4'] else 'no'} "
                      f"| {row['pull_succeeds_from']} |", flush=True)
            else:
                print(f"| {seed} | {r} | no pull | | | | | | |", flush=True)
    with_pull = [x for x in rows if x["pull"]]
    if with_pull:
        ratio = [x["pull_4"] / max(x["pull_1"], 1e-9) for x in with_pull]
        print(f"\n{len(with_pull)} of {len(rows)} robots with a pull: pull's C1 in situation 1 median "
              f"{statistics.median(x['pull_1'] for x in with_pull):.3f}, in situation 4 median "
              f"{statistics.median(x['pull_4'] for x in with_pull):.3f} (ratio 4/1 median {statistics.median(ratio):.2f}, "
              f"range {min(ratio):.2f}-{max(ratio):.2f}); the pull C1's strongest unit in situation 4 in "
              f"{sum(x['pull_top_in_4'] for x in with_pull)} of {len(with_pull)}; "
              f"{time.process_time() - c0:.0f} CPU-s")


if __name__ == "__main__":
    main()
