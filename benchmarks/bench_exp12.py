"""Time Experiments 1 and 2 at the full protocol, batched, against running the participants one by
one; and check that the SOM training methods agree on Experiment 2's M1_1.

Usage::

    python benchmarks/bench_exp12.py [exp1|exp2] [participants] [extra overrides...]
    python benchmarks/bench_exp12.py som [steps]     # M1_1: windowed / factored vs online
"""
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


def som_equivalence(steps: int) -> None:
    """M1_1 (64x64, 6,200 inputs, 98 patterns), 2 participants, the configured schedule compressed
    to ``steps``: winners, quantisation / topographic errors and weights of each method."""
    from neuroimagery.experiments.exp2 import Exp2Config
    from neuroimagery.nn.som import fit_windowed as som_fit_windowed
    from neuroimagery.models.rotation_motor import ANGLES, MotorRotationModel
    from neuroimagery.nn import SOM, participant_generators

    e = Exp2Config(som_iterations=steps)
    m = MotorRotationModel(e, 2, 0)
    ang = torch.tensor(ANGLES)
    o, c, d = (t.reshape(-1) for t in torch.meshgrid(torch.arange(2), torch.arange(7), torch.arange(7), indexing="ij"))
    X = torch.cat([m.ss_code(o, ang[c]), m.pmc1_code(ang[d])], -1)
    b = m.babble(steps)
    order = b["obj"] * 49 + b["cur"] * 7 + b["des"]
    res = {}
    for method in ("online", "factored", "windowed"):
        som = SOM((64, 64), 6200, generators=participant_generators(0, 2, stream=6), init=(0.0, e.init_high),
                  eta=e.som_eta, eta_final=e.som_eta_final, sigma=e.som_sigma, sigma_final=e.som_sigma_final,
                  iterations=steps)
        som.rule.cutoff = e.som_cutoff
        som.train()
        t = time.perf_counter()
        win = som_fit_windowed(som, X, order) if method == "windowed" else som.fit(X, order=order, method=method)
        dt = time.perf_counter() - t
        res[method] = (win, som.weight.clone())
        print(f"{method:9s} {dt:6.1f} s  QE {som.quantization_error(X).tolist()}  TE {som.topographic_error(X).tolist()}")
    for method in ("factored", "windowed"):
        same = (res[method][0] == res["online"][0]).float().mean().item()
        dw = (res[method][1] - res["online"][1]).abs().max().item()
        print(f"{method} vs online: winners identical {same:.1%}, max |weight difference| {dw:.2e}")


def main():
    register_configs()
    torch.set_num_threads(2)
    exp = sys.argv[1] if len(sys.argv) > 1 else "exp1"
    if exp == "som":
        som_equivalence(int(sys.argv[2]) if len(sys.argv) > 2 else 200)
        return
    P = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    extra = sys.argv[3:]
    batched = run(exp, [f"participants={P}"] + extra)
    one = run(exp, ["participants=1"] + extra)
    print(f"{exp}: {P} participants batched {batched:.1f} s; one participant {one:.1f} s; "
          f"one by one (estimated {P} x) {P * one:.1f} s; ratio {P * one / batched:.2f}")


if __name__ == "__main__":
    main()
