"""W1-W4 of one candidate world of the calibration (docs/world_calibration.md), measured with the
acceptance code itself: ``robot.babble``'s counts (W1) and ``exp5_world``'s libraries and summary
(W2-W4), in the candidate's ``WorldConfig``. Every piece (a posture and seed's counts, a library)
is kept in the candidate's folder as it is done and reused by a rerun with the same settings, so
a stopped screen or confirmation resumes.

Also the rule that picks a world from the front (:func:`rank_key`) and the front itself
(:func:`pareto`).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from ...core.files import kept_json
from ...robot.babble import POSSIBLE_RATE, THESIS_EVENTS, agreement, kept_counts
from ...robot.movements import MovementConfig
from .world import one_library, summarise

SEED0 = 100  # the calibration's seeds start here (seeds 0-9 and 17 are never used by the search)


def candidate_key(params: dict) -> str:
    """A short name of a parameter set (its folder under the search's work folder)."""
    text = json.dumps({k: (round(v, 6) if isinstance(v, float) else v) for k, v in sorted(params.items())})
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def event_table(cfg, weight_sigma: float, n: int, seeds: list[int], folder: Path) -> dict:
    """W1: the rates of the six events over ``n`` exploration movements per posture and seed
    (``robot.babble``'s streams), and the cells agreeing with Table 7.1 at the 1 % threshold."""
    import torch

    from ...robot.world import ToolWorld

    torch.set_num_threads(1)
    moves = MovementConfig(weight_sigma=float(weight_sigma), dt=cfg.control_dt)
    world = ToolWorld(cfg)
    try:
        counts = {(k, s): kept_counts(k, n, s, moves, cfg, folder, world=world) for k in range(1, 5) for s in seeds}
    finally:
        world.close()
    total = len(seeds) * n
    rates = {f"posture-{k}": [round(sum(counts[(k, s)][i] for s in seeds) / total, 5) for i in range(6)]
             for k in range(1, 5)}
    return dict(rates=rates, w1=agreement(rates, THESIS_EVENTS, POSSIBLE_RATE), movements_per_posture=total)


def libraries(cfg, weight_sigma: float, n: int, seeds: list[int], folder: Path) -> list[dict]:
    """``n`` skill libraries per seed acquired as ``exp5_world`` does, in the candidate world."""
    env = dict(explore_weight_sigma=float(weight_sigma))
    settings = dict(world=asdict(cfg), env=env)
    return [kept_json(folder / "libraries" / f"seed{s}_{i:04d}.json", settings,
                      lambda s=s, i=i: dict(one_library(s, i, world_config=cfg, env_kwargs=env), seed=s))
            for s in seeds for i in range(n)]


def measure(cfg, weight_sigma: float, folder: Path, babble_n: int, babble_seeds: list[int],
            libraries_n: int, library_seeds: list[int]) -> dict:
    """W1-W4 of the candidate (docs/contracts.md's definitions, thresholds unchanged)."""
    events = event_table(cfg, weight_sigma, babble_n, babble_seeds, folder)
    s = summarise(libraries(cfg, weight_sigma, libraries_n, library_seeds, folder))
    w3 = s["pull_alone_share"] if s["with_pull"] else 1.0  # no library with a pull: the worst
    return dict(w1=events["w1"], w2=s["skill_agreement"][str(POSSIBLE_RATE)], w3=w3, w4=s["move_then_pull_share"],
                pull_alone=s["pull_alone_from_4"], with_pull=s["with_pull"], routes=s["move_then_pull"],
                libraries=s["libraries"], event_rates=events["rates"], skill_rates=s["skill_rates"],
                movements_per_posture=events["movements_per_posture"])


def rank_key(m: dict) -> tuple:
    """The rule that picks the world (docs/world_calibration.md): W3 under 5 %, then W4 more than
    half, then most W1 + W2 cells, then the lowest W3, then the highest W4. Smaller is better."""
    return (not m["w3"] < 0.05, not m["w4"] > 0.5, -(m["w1"] + m["w2"]), m["w3"], -m["w4"])


def pareto(items: list[tuple]) -> list[tuple]:
    """The ``(name, measures)`` pairs no other pair dominates on (W3 low, W4 high, W1 + W2 high)."""
    def obj(m):
        return (m["w3"], -m["w4"], -(m["w1"] + m["w2"]))

    front = []
    for name, m in items:
        a = obj(m)
        if not any(all(x <= y for x, y in zip(obj(o), a)) and obj(o) != a for _, o in items):
            front.append((name, m))
    return sorted(front, key=lambda nm: rank_key(nm[1]))
