"""Throughput of Experiments 3 and 4: trials per second of the batched run of all participants,
and the ratio against running the participants one at a time.

    python benchmarks/bench_exp34.py [participants] [quick|full]

Peak memory: the process's peak resident set during the batched run (neuroimagery/core/memory.py).
"""
import sys
import time
from pathlib import Path

from hydra import compose, initialize_config_dir

from neuroimagery.core import memory
from neuroimagery.config import register_configs, validate
from neuroimagery.experiments.exp3 import protocol as exp3
from neuroimagery.experiments.exp4 import protocol as exp4


def _cfg(name, participants, preset):
    register_configs()
    with initialize_config_dir(config_dir=str(Path(__file__).resolve().parents[1] / "conf"), version_base="1.3"):
        cfg = validate(compose("config", overrides=[f"experiment={name}", f"participants={participants}", "logger=none"]))
    cfg.preset = preset
    return cfg


def bench(mod, name, participants, preset):
    cfg = _cfg(name, participants, preset)
    memory.reset_peak()
    t0 = time.perf_counter()
    model = mod.train_model(cfg, list(range(participants)))
    t1 = time.perf_counter()
    df, _, _ = mod.run_tests(cfg, model)
    t2 = time.perf_counter()
    peak = memory.peak_rss_mb()
    solo = 0.0
    for p in range(participants):
        s0 = time.perf_counter()
        m = mod.train_model(cfg, [p])
        mod.run_tests(cfg, m)
        solo += time.perf_counter() - s0
    batched = t2 - t0
    print(f"{name}: {len(df)} trials, train {t1 - t0:.1f} s, evaluate {t2 - t1:.1f} s, "
          f"{len(df) / (t2 - t1):.0f} trials/s; batched {batched:.1f} s vs one at a time {solo:.1f} s "
          f"(ratio {solo / batched:.2f}); peak resident memory of the batched run (train + test) {peak} MiB")


if __name__ == "__main__":
    P = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    preset = sys.argv[2] if len(sys.argv) > 2 else "full"
    bench(exp3, "exp3", P, preset)
    bench(exp4, "exp4", P, preset)
