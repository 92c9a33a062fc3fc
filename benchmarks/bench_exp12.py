"""Time Experiments 1 and 2 at the full protocol, batched, and against running the participants
one by one. Usage: ``python benchmarks/bench_exp12.py [exp1|exp2] [participants] [extra overrides...]``."""
import sys
import tempfile
import time

import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs
from neuroimagery.run import evaluate


def run(exp, overrides):
    with initialize_config_dir(config_dir=__file__.rsplit("/benchmarks", 1)[0] + "/conf", version_base="1.3"):
        cfg = compose("config", overrides=[f"experiment={exp}", "logger=none", "progress=false"] + overrides)
    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        evaluate(cfg, out_dir=d)
    return time.perf_counter() - t


def main():
    register_configs()
    torch.set_num_threads(2)
    exp = sys.argv[1] if len(sys.argv) > 1 else "exp1"
    P = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    extra = sys.argv[3:]
    batched = run(exp, [f"participants={P}"] + extra)
    one = run(exp, ["participants=1"] + extra)
    print(f"{exp}: {P} participants batched {batched:.1f} s; one participant {one:.1f} s; "
          f"one by one (estimated {P} x) {P * one:.1f} s; ratio {P * one / batched:.2f}")


if __name__ == "__main__":
    main()
