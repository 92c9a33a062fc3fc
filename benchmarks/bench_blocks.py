"""Throughput of the local learning rules at the thesis's map sizes, as ratios measured in one run.

* Hebbian (outstar, eq. 4.2) on a 1024 -> 3255 connection (PC 32x32 -> PMC_1 31x105, Exp. 1) and
  delta rule (eq. 6.4) on 1024 -> 1024 (Exp. 3/4 forward models): torch, batched over trials and
  participants, against NumPy applying the same equation one pattern at a time.
* Kohonen SOM 64x64 on 2048-dim input (PFC_2 of Exp. 2): against MiniSom (``pip install minisom``)
  on the same map and input, iterations per second per SOM. Ours runs P participants at once,
  with the online rule and with the exact factored form (``SOM.fit(method='factored')``, valid
  when the training set has fewer patterns than inputs: here 196, the pairs of Exp. 2).

Usage: ``python benchmarks/bench_blocks.py [--quick]``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from neuroimagery.nn import SOM, AllToAll, Delta, Hebbian, participant_generators


def timed(fn, repeat=1):
    fn()  # warm-up
    t = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t) / repeat


def bench_hebbian(P, B, quick):
    n_in, n_out, eta = 1024, 3255, 0.01
    x = torch.rand(P, B, n_in)
    y = torch.rand(P, B, n_out)
    conn = AllToAll(n_in, n_out, participants=P, rules=Hebbian(eta))
    t_torch = timed(lambda: conn.learn(x, y), 2 if quick else 5) / (P * B)
    W = np.random.rand(n_out, n_in).astype(np.float32)
    xs, ys = x[0].numpy(), y[0].numpy()
    k = 2 if quick else 4

    def numpy_loop():
        nonlocal W
        for b in range(k):
            W += eta * xs[b][None, :] * (ys[b][:, None] - W)

    t_np = timed(numpy_loop) / k
    return t_torch, t_np


def bench_delta(P, B, quick):
    n, eta = 1024, 0.1
    x = torch.rand(P, B, n)
    tgt = torch.rand(P, B, n)
    conn = AllToAll(n, n, participants=P, rules=Delta(eta))
    t_torch = timed(lambda: conn.learn(x, conn(x), target=tgt), 2 if quick else 5) / (P * B)
    W = np.random.rand(n, n).astype(np.float32)
    xs, ts = x[0].numpy(), tgt[0].numpy()
    k = 4 if quick else 16

    def numpy_loop():
        nonlocal W
        for b in range(k):
            a = W @ xs[b]
            W += eta * np.outer(ts[b] - a, xs[b])

    t_np = timed(numpy_loop) / k
    return t_torch, t_np


def bench_som(P, iters, quick):
    from minisom import MiniSom

    n_in, N = 2048, 196
    X = (torch.rand(N, n_in, generator=torch.Generator().manual_seed(0)) > 0.9).float()
    ms = MiniSom(64, 64, n_in, sigma=32, learning_rate=0.1, random_seed=0)
    m_iters = 20 if quick else 60
    t = time.perf_counter()
    ms.train(X.numpy(), m_iters, random_order=True)
    t_minisom = (time.perf_counter() - t) / m_iters
    res = {}
    # ours: a whole decay schedule (sigma 32 -> 0.5) compressed into `iters` steps, so the share of
    # steps with a map-wide neighbourhood is that of the thesis's 10,000-step schedule
    for method, n_it in (("online", max(20, iters // 20)), ("factored", iters)):
        som = SOM((64, 64), n_in, participants=P, iterations=iters if method == "factored" else 10_000)
        gens = participant_generators(0, P)
        t = time.perf_counter()
        som.fit(X, iterations=n_it, generators=gens, method=method)
        res[method] = (time.perf_counter() - t) / (n_it * P)
    return t_minisom, res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--participants", type=int, default=10)
    ap.add_argument("--batch", type=int, default=16, help="patterns per participant per update")
    a = ap.parse_args()
    P = a.participants
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, participants batched: {P}, patterns per update: {a.batch}")
    th, nh = bench_hebbian(P, a.batch, a.quick)
    print(f"Hebbian 1024->3255 : torch {1 / th:9.1f} patterns/s   numpy per-pattern {1 / nh:8.1f}/s   ratio {nh / th:6.1f}x")
    td, nd = bench_delta(P, a.batch, a.quick)
    print(f"Delta   1024->1024 : torch {1 / td:9.1f} patterns/s   numpy per-pattern {1 / nd:8.1f}/s   ratio {nd / td:6.1f}x")
    tm, res = bench_som(P, 500 if a.quick else 2000, a.quick)
    print(f"SOM 64x64, 2048 in : MiniSom {1 / tm:8.1f} it/s")
    for method, t in res.items():
        print(f"   ours {method:9s}: {1 / t:9.1f} it/s per SOM   ratio {tm / t:7.1f}x MiniSom")


if __name__ == "__main__":
    main()
