"""What running the models on the blocks costs: CPU seconds (``time.process_time``, one thread) of

* ``exp4``: Experiment 4's training and every test's trials for one seed (``train_model`` +
  ``run_tests``; ``participants`` participants, default 10);
* ``exp6``: Experiment 6's training of one participant (completion map, forward models, the
  confirm stage's cut; the pybullet views included);
* ``exp5``: :class:`~neuroimagery.models.tool_use.ToolUseBrain`'s read-outs and learning over a
  fixed batch of synthetic rollouts on the 2 x 240 x 320 PC map (no physics, no eye): for each
  rollout C1, C2, C4 and PMC read, C1 and C2 outstar steps, a C3 pair learnt and recalled, a
  mental image, a Q-learning step.

    python benchmarks/blocks_overhead.py exp4 [full|quick] [participants] [seed]
    python benchmarks/blocks_overhead.py exp6 [full|quick] [seed]
    python benchmarks/blocks_overhead.py exp5 [rollouts (400)] [seed]

Each prints one line ``<what>: <cpu> CPU-s``; take the smallest of a few runs on a shared machine.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

from neuroimagery.config import register_configs, validate  # noqa: E402

CONF = Path(__file__).resolve().parents[1] / "conf"


def _cfg(name: str, participants: int, preset: str, seed: int):
    register_configs()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = validate(compose("config", overrides=[f"experiment={name}", f"participants={participants}",
                                                    f"seed={seed}", "logger=none", "progress=false"]))
    cfg.preset = preset
    return cfg


def exp4(preset: str = "full", participants: int = 10, seed: int = 0) -> float:
    from neuroimagery.experiments.exp4 import protocol as mod

    cfg = _cfg("exp4", participants, preset, seed)
    c0 = time.process_time()
    model = mod.train_model(cfg, list(range(participants)))
    df, _, _ = mod.run_tests(cfg, model)
    cpu = time.process_time() - c0
    print(f"exp4 {preset} seed={seed} P={participants} train+trials ({len(df)} trials): {cpu:.2f} CPU-s")
    return cpu


def exp6(preset: str = "full", seed: int = 0) -> float:
    from neuroimagery.experiments.exp6 import protocol as mod
    from neuroimagery.experiments.exp6.data import make_scene

    cfg = _cfg("exp6", 1, preset, seed)
    scene = make_scene(cfg.experiment)
    try:
        c0 = time.process_time()
        mod.train_model(cfg, [0], scene)
        cpu = time.process_time() - c0
    finally:
        scene.close()
    print(f"exp6 {preset} seed={seed} training of one participant: {cpu:.2f} CPU-s")
    return cpu


POOL = 16  # distinct situation images of the exp5 benchmark


def exp5(rollouts: int = 400, seed: int = 0) -> float:
    from neuroimagery.models.tool_use.brain import ToolUseBrain

    H, W = 240, 320
    g = torch.Generator().manual_seed(seed)
    brain = ToolUseBrain((H, W), seed=seed)
    images = (torch.rand(POOL, 2, H, W, generator=g) < 0.02).float()  # the rollouts cycle through a pool
    units = torch.randint(brain.n_dmps, (rollouts,), generator=g).tolist()
    c0 = time.process_time()
    total = 0.0
    for k in range(rollouts):
        x0, x1, u = images[k % POOL], images[(k + 1) % POOL], units[k]
        total += float(brain.pmc(x0).sum() + brain.distal_goals(x0).sum())
        brain.train_c1(x0, u, 1.0, 5)
        brain.train_c2(x0, k % brain.n_goals, 5)
        brain.train_c3(x0, u, 1 + k % 4, x1, 5, g)
        total += float(brain.imagine(x0, u).sum())
        brain.q_update(x0, u, 1.0 if k % 3 == 0 else 0.0, x1, k % 5 == 4)
    total += sum(float(m.sum()) for m in brain.maps({"a": 0, "b": 1}).values())
    cpu = time.process_time() - c0
    print(f"exp5 ToolUseBrain {rollouts} rollouts seed={seed}: {cpu:.2f} CPU-s (check value {total:.6g})")
    return cpu


if __name__ == "__main__":
    torch.set_num_threads(1)
    what, args = sys.argv[1], sys.argv[2:]
    if what == "exp4":
        exp4(args[0] if args else "full", int(args[1]) if len(args) > 1 else 10, int(args[2]) if len(args) > 2 else 0)
    elif what == "exp6":
        exp6(args[0] if args else "full", int(args[1]) if len(args) > 1 else 0)
    elif what == "exp5":
        exp5(int(args[0]) if args else 400, int(args[1]) if len(args) > 1 else 0)
    else:
        sys.exit(f"error: unknown benchmark {what!r} (exp4, exp5, exp6)")
