"""Time Experiments 1 and 2 at the full protocol, batched, against running the participants one by
one; and check that the SOM training methods agree on Experiment 2's M1_1.

Usage::

    python benchmarks/bench_exp12.py [exp1|exp2|both] [participants] [extra overrides...] [--solo | --batched]
    python benchmarks/bench_exp12.py som [steps]     # M1_1: windowed (by pieces) / factored vs online

Each run is ``evaluate`` (train, then test) in this process; wall and CPU time are printed (the
machine may be shared: CPU time is the steadier number). One by one = ``participants`` separate
runs of one participant each, estimated as ``participants`` x one such run (``--solo`` runs them
all: every participant of a batched run has its own seed streams, so the sum is the real cost;
``--batched`` skips them). The last line adds up Experiments 1 and 2: wall and CPU time, and how
much of it went to training and to the tests.
"""
import os
import sys
import tempfile
import time

import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs
from neuroimagery.app.run import evaluate


def run(exp, overrides):
    with initialize_config_dir(config_dir=__file__.rsplit("/benchmarks", 1)[0] + "/conf", version_base="1.3"):
        cfg = compose("config", overrides=[f"experiment={exp}", "logger=none", "progress=false"] + overrides)
    t, c = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory() as d:
        s = evaluate(cfg, out_dir=d)
    return time.perf_counter() - t, time.process_time() - c, {**s.get("runtime_s", {}), "peak_rss_mb": s.get("peak_rss_mb", {})}


def som_equivalence(steps: int) -> None:
    """M1_1 (64x64, 6,200 inputs, 98 patterns), 2 participants, the configured schedule compressed
    to ``steps``: winners, quantisation / topographic errors and weights of each method."""
    from neuroimagery.experiments.exp2.protocol import Exp2Config
    from neuroimagery.models.params import SomParams
    from neuroimagery.models.rotation_motor import ANGLES, MotorRotationModel
    from neuroimagery.nn import SOM, participant_generators
    from neuroimagery.nn.som_windowed import fit_windowed

    e = Exp2Config(som=SomParams(iterations=steps, cutoff=0.01, cluster_sigma=1.0))
    m = MotorRotationModel(e, 2, 0)
    ang = torch.tensor(ANGLES)
    o, c, d = (t.reshape(-1) for t in torch.meshgrid(torch.arange(2), torch.arange(7), torch.arange(7), indexing="ij"))
    X = torch.cat([m.ss_code(o, ang[c]), m.pmc1_code(ang[d])], -1)
    b = m.babble(steps)
    order = b["obj"] * 49 + b["cur"] * 7 + b["des"]
    res = {}
    for method in ("online", "factored", "windowed", "windowed by pieces"):
        som = SOM((64, 64), 6200, generators=participant_generators(0, 2, stream=6), init=(0.0, e.init_high),
                  eta=e.som.eta, eta_final=e.som.eta_final, sigma=e.som.sigma, sigma_final=e.som.sigma_final,
                  iterations=steps)
        som.rule.cutoff = e.som.cutoff
        som.train()
        t = time.process_time()
        if method.startswith("windowed"):
            win = fit_windowed(som, X, order, parts=(3100, 3100) if method.endswith("pieces") else None)
        else:
            win = som.fit(X, order=order, method=method)
        dt = time.process_time() - t
        res[method] = (win, som.weight.clone())
        print(f"{method:18s} {dt:6.1f} s CPU  QE {som.quantization_error(X).tolist()}  TE {som.topographic_error(X).tolist()}")
    for method in ("factored", "windowed", "windowed by pieces"):
        same = (res[method][0] == res["online"][0]).float().mean().item()
        dw = (res[method][1] - res["online"][1]).abs().max().item()
        print(f"{method} vs online: winners identical {same:.1%}, max |weight difference| {dw:.2e}")


def main():
    register_configs()
    args = [a for a in sys.argv[1:] if a not in ("--solo", "--batched")]
    solo, batched = "--solo" in sys.argv, "--batched" in sys.argv
    exp = args[0] if args else "both"
    if exp == "som":
        som_equivalence(int(args[1]) if len(args) > 1 else 200)
        return
    P = int(args[1]) if len(args) > 1 else 10
    extra = args[2:]
    print(f"torch threads {torch.get_num_threads()} (OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}); "
          "the experiments run on experiment.auto_threads unless threads=N is given")
    total = [0.0, 0.0, 0.0, 0.0]  # wall, CPU, train, test
    for ex in (["exp1", "exp2"] if exp == "both" else [exp]):
        wall, cpu, parts = run(ex, [f"participants={P}"] + extra)
        total[0] += wall
        total[1] += cpu
        total[2] += parts.get("train") or 0.0
        total[3] += parts.get("evaluate") or 0.0
        mem = parts["peak_rss_mb"]
        print(f"{ex}: {P} participants batched: {wall:.1f} s wall, {cpu:.1f} s CPU (train {parts.get('train')} s, "
              f"test {parts.get('evaluate')} s); peak resident memory of this process: train {mem.get('train')} MiB, "
              f"test {mem.get('evaluate')} MiB", flush=True)
        if batched:
            continue
        if solo:
            one = [run(ex, ["participants=1", f"seed={s}"] + extra)[:2] for s in range(P)]
            ow, oc = sum(x[0] for x in one), sum(x[1] for x in one)
            how = f"{P} runs"
        else:
            ow, oc = (P * x for x in run(ex, ["participants=1"] + extra)[:2])
            how = f"estimated {P} x one run"
        print(f"{ex}: one by one ({how}): {ow:.1f} s wall, {oc:.1f} s CPU; ratio {ow / wall:.2f} (wall), "
              f"{oc / cpu:.2f} (CPU)", flush=True)
    if exp == "both":
        print(f"exp1 + exp2 batched: {total[0]:.1f} s wall, {total[1]:.1f} s CPU (train {total[2]:.1f} s, "
              f"test {total[3]:.1f} s)")


if __name__ == "__main__":
    main()
