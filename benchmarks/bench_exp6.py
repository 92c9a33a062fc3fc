"""Throughput of Experiment 6: training time and trials per second of the batched test of all
participants (the pybullet views included).

    python benchmarks/bench_exp6.py [participants] [quick|full]
"""
import sys
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs, validate
from neuroimagery.experiments import exp6


def main(participants: int = 10, preset: str = "full") -> None:
    register_configs()
    with initialize_config_dir(config_dir=str(Path(__file__).resolve().parents[1] / "conf"), version_base="1.3"):
        cfg = validate(compose("config", overrides=["experiment=exp6", f"participants={participants}", "logger=none"]))
    cfg.preset = preset
    c0, t0 = time.process_time(), time.perf_counter()
    model = exp6.train_model(cfg, list(range(participants)))
    c1, t1 = time.process_time(), time.perf_counter()
    df, _, _ = exp6.run_tests(cfg, model)
    c2, t2 = time.process_time(), time.perf_counter()
    print(f"exp6 ({preset}, {participants} participants, {torch.get_num_threads()} threads): train {t1 - t0:.1f} s "
          f"(CPU {c1 - c0:.1f} s), test {len(df)} trials in {t2 - t1:.1f} s (CPU {c2 - c1:.1f} s): "
          f"{len(df) / (t2 - t1):.0f} trials/s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10, sys.argv[2] if len(sys.argv) > 2 else "full")
