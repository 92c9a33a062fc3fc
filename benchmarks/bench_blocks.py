"""Throughput of the building blocks against reference libraries, as ratios measured in one run.

Each comparison runs both sides in this process, back to back, ``--repeat`` times; the ratio
printed is the median over the repetitions (the medians of each side are printed too). Every
reference is checked to converge on the problem it is timed on (a line ``check:`` per block), so a
ratio never times a diverging loop:

* Hebbian (outstar, eq. 4.2) 1024 -> 3255 (PC 32x32 -> PMC_1 31x105, Exp. 1) and delta rule
  (eq. 6.4) 1024 -> 1024 (Exp. 3/4 forward models): torch, batched over patterns and
  participants, against NumPy applying the same equation one pattern at a time. The delta rule's
  inputs have unit norm (LMS is stable for ``eta |x|^2 < 2``), the same inputs on both sides; NumPy
  runs with floating-point errors raised.
* Kohonen SOM 64x64 on 2048-dim input (PFC_2 of Exp. 2) against MiniSom, iterations per second
  per SOM: the exact online step (``SOM.fit(method='online')``, every unit updated at every
  presentation, alone and 10 participants batched; ``neuroimagery.nn.som_online``), the same with
  each update applied as it happens (``fold=False``), and apart: the truncated neighbourhood
  (``truncate=3`` sigmas) and the factored form (valid with fewer patterns than inputs). Our
  maps keep sigma at 32 so that every unit has a rate above zero at every step (printed).
* DMP rollouts (eq. 7.2-7.5, 7 joints, 4 basis functions, 200 Euler steps): ``motor.dmp.DMP``
  batched against pydmps one rollout at a time (same step count).
* Forward kinematics of the iCub arm: ``robot.kinematics.ArmKinematics`` batched against
  pybullet setting the joints and reading ``getLinkStates`` one configuration at a time.

Usage: ``python benchmarks/bench_blocks.py [--quick] [--threads N] [--repeat R]``. Optional
packages: ``pip install -e ".[bench]"`` (MiniSom, pydmps); a block whose reference is missing says
so and is skipped.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time


def _args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps and one repetition")
    ap.add_argument("--threads", type=int, default=1, help="torch and BLAS threads on both sides (default 1)")
    ap.add_argument("--repeat", type=int, default=None, help="repetitions per comparison (default 3, 1 with --quick)")
    ap.add_argument("--participants", type=int, default=10)
    ap.add_argument("--batch", type=int, default=16, help="patterns per participant per update (Hebbian, delta)")
    return ap.parse_args()


ARGS = _args() if __name__ == "__main__" else None
if ARGS is not None:  # BLAS threads are read when NumPy loads
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.threads)

import numpy as np  # noqa: E402
import torch  # noqa: E402

from neuroimagery.nn import SOM, AllToAll, Delta, Hebbian, participant_generators, seeding, som_online  # noqa: E402

SPENT: dict[str, float] = {}


def side_by_side(name, ours, ref, repeat):
    """Median seconds per unit of each side over ``repeat`` back-to-back rounds, and the median ratio."""
    o, r = [], []
    t0 = time.perf_counter()
    for _ in range(repeat):
        o.append(ours())
        r.append(ref())
    SPENT[name] = time.perf_counter() - t0
    ratio = statistics.median(b / a for a, b in zip(o, r))
    return statistics.median(o), statistics.median(r), ratio


def line(label, t_ours, t_ref, ratio, unit, ref_name):
    print(f"{label:34s} ours {1 / t_ours:10.1f} {unit}   {ref_name} {1 / t_ref:9.1f} {unit}   ratio {ratio:7.1f}x")


# ---------------------------------------------------------------------------------------------- rules
def bench_hebbian(P, B, repeat, quick):
    n_in, n_out, eta = 1024, 3255, 0.01
    g = torch.Generator().manual_seed(0)
    x, y = torch.rand(P, B, n_in, generator=g), torch.rand(P, B, n_out, generator=g)
    conn = AllToAll(n_in, n_out, participants=P, rules=Hebbian(eta))
    W = np.random.default_rng(0).random((n_out, n_in), dtype=np.float32) * 0.1
    xs, ys = x[0].numpy(), y[0].numpy()
    k = 2 if quick else 4
    steps = []

    def ours():
        conn.learn(x, y)
        t = time.perf_counter()
        for _ in range(2):
            conn.learn(x, y)
        return (time.perf_counter() - t) / (2 * P * B)

    def ref():
        t = time.perf_counter()
        with np.errstate(all="raise"):
            for b in range(k):
                d = eta * xs[b][None, :] * (ys[b][:, None] - W)
                W[...] += d
        steps.append(float(np.abs(d).max()))
        return (time.perf_counter() - t) / k

    res = side_by_side("hebbian", ours, ref, repeat)
    line("Hebbian 1024->3255 (per pattern)", *res, "patterns/s", "numpy")
    one = AllToAll(n_in, n_out, participants=1, rules=Hebbian(eta))
    W1 = one.weight[0].numpy().copy()
    for b in range(3):  # the same equation, one pattern at a time, on both sides
        one.learn(x[:1, b:b + 1], y[:1, b:b + 1])
        W1 += eta * xs[b][None, :] * (ys[b][:, None] - W1)
    print(f"   check: numpy weights finite and within [0, 1] (each update is a convex combination) "
          f"{bool(np.isfinite(W).all() and W.min() >= 0 and W.max() <= 1)}; largest change per update {steps[-1]:.1e}; "
          f"torch and numpy weights after 3 patterns differ by {float(np.abs(one.weight[0].numpy() - W1).max()):.1e}")
    return res


def bench_delta(P, B, repeat, quick):
    n, eta = 1024, 0.1
    g = torch.Generator().manual_seed(1)
    x = torch.rand(P, B, n, generator=g)
    x = x / x.norm(dim=-1, keepdim=True)  # unit inputs: eta |x|^2 = 0.1, the LMS step is stable
    tgt = torch.rand(P, B, n, generator=g)
    conn = AllToAll(n, n, participants=P, rules=Delta(eta, reduction="mean"))
    W = np.zeros((n, n), dtype=np.float32)
    xs, ts = x[0].numpy(), tgt[0].numpy()
    k = 4 if quick else 16

    def residual_np():
        return float(np.sqrt(np.mean((ts - xs @ W.T) ** 2)))

    def residual_torch():
        return float((tgt - conn(x)).pow(2).mean().sqrt())

    r_np0, r_t0 = residual_np(), residual_torch()

    def ours():
        conn.learn(x, conn(x), target=tgt)
        t = time.perf_counter()
        for _ in range(2):
            conn.learn(x, conn(x), target=tgt)
        return (time.perf_counter() - t) / (2 * P * B)

    def ref():
        t = time.perf_counter()
        with np.errstate(all="raise"):
            for i in range(k):
                b = i % B
                a = W @ xs[b]
                W[...] += eta * np.outer(ts[b] - a, xs[b])
        return (time.perf_counter() - t) / k

    res = side_by_side("delta", ours, ref, repeat)
    line("Delta 1024->1024 (per pattern)", *res, "patterns/s", "numpy")
    r_np1, r_t1 = residual_np(), residual_torch()
    with np.errstate(all="raise"):  # untimed: on until the residual settles
        for i in range(40 * B):
            b = i % B
            W[...] += eta * np.outer(ts[b] - W @ xs[b], xs[b])
    for _ in range(200):
        conn.learn(x, conn(x), target=tgt)
    print(f"   check: RMS residual |t - W x| on the timed patterns: numpy {r_np0:.3f} -> {r_np1:.3f} (timed) -> "
          f"{residual_np():.3f} (40 more passes), torch {r_t0:.3f} -> {r_t1:.3f} -> {residual_torch():.3f} (200 more "
          "updates): both converge")
    return res


# ----------------------------------------------------------------------------------------------- SOM
def bench_som(P, repeat, quick):
    try:
        from minisom import MiniSom
    except ImportError:
        print("SOM: MiniSom not installed (pip install minisom): skipped")
        return None
    n_in, N = 2048, 196
    X = (torch.rand(N, n_in, generator=torch.Generator().manual_seed(0)) > 0.9).float()
    Xn = X.numpy()
    ms = MiniSom(64, 64, n_in, sigma=32, learning_rate=0.1, random_seed=0)
    qe_ms0 = ms.quantization_error(Xn)
    m_iters = 15 if quick else 30
    steps = 32 if quick else 64

    def minisom():
        t = time.perf_counter()
        ms.train(Xn, m_iters, random_order=True)
        return (time.perf_counter() - t) / m_iters

    def make(P, sigma=32.0, **kw):
        som = SOM((64, 64), n_in, participants=P, seed=0, eta=0.1, sigma=sigma, eta_final=0.05, sigma_final=sigma,
                  iterations=10_000)
        XP = X.unsqueeze(0).expand(P, -1, -1)
        gens = participant_generators(0, P, stream=1)

        def run():
            order = seeding.randint(gens, N, (steps,))
            t = time.perf_counter()
            som_online.fit_online(som, XP, order, **kw)
            return (time.perf_counter() - t) / (steps * P)

        return som, run

    results = {}
    cases = [("online, 1 map", 1, {}), (f"online, {P} maps batched", P, {}),
             ("online fold=False, 1 map", 1, dict(fold=False)), (f"online fold=False, {P} maps", P, dict(fold=False))]
    soms = {}
    for label, p, kw in cases:
        som, run = make(p, **kw)
        soms[label] = som
        qe0 = float(som.quantization_error(X).mean())
        results[label] = side_by_side(f"som {label}", run, minisom, repeat)
        line(f"SOM 64x64/2048 {label}", *results[label], "it/s", "MiniSom")
        print(f"   check: quantisation error ours {qe0:.2f} -> {float(som.quantization_error(X).mean()):.2f}")
    print(f"   check: MiniSom quantisation error {qe_ms0:.2f} -> {ms.quantization_error(Xn):.2f}")
    th = som_online._axis_gaussians((64, 64), torch.tensor([0]), torch.tensor(32.0), [torch.arange(64.0)] * 2, None)
    print(f"   every unit moves at every step: smallest rate on the map {0.05 * float(th.min()):.1e} > 0 (sigma 32)")
    # apart: the truncated neighbourhood (a named option) against the exact step at the same sigma
    som_e, run_e = make(1, sigma=3.0)
    som_t, run_t = make(1, sigma=3.0, truncate=3.0)
    t_e, t_t, r = side_by_side("som truncate", run_e, run_t, repeat)
    print(f"{'SOM sigma=3, truncate=3 sigmas':34s} exact {1 / t_e:9.1f} it/s   truncated {1 / t_t:9.1f} it/s   "
          f"truncated/exact speed {1 / r:5.2f}x (changes the map: max |dw| "
          f"{float((som_e.weight - som_t.weight).abs().max()):.1e})")
    # apart: the factored form, valid only when the map sees fewer patterns than inputs; each round
    # a fresh map and a whole decay schedule (sigma 32 -> 0.5) compressed into n_f steps
    n_f = 100 if quick else 300

    def factored():
        fac = SOM((64, 64), n_in, participants=P, iterations=n_f)
        t = time.perf_counter()
        fac.fit(X, iterations=n_f, generators=participant_generators(0, P), method="factored")
        return (time.perf_counter() - t) / (n_f * P)

    line("SOM factored (N=196 < 2048 inputs)", *side_by_side("som factored", factored, minisom, repeat), "it/s",
         "MiniSom")
    return results


def som_profile(P):
    """Where the online kernel's time goes: the largest torch operators of 64 steps."""
    from torch.profiler import ProfilerActivity, profile

    from neuroimagery.core.native import quiet_native_output

    X = (torch.rand(196, 2048, generator=torch.Generator().manual_seed(0)) > 0.9).float()
    som = SOM((64, 64), 2048, participants=P, sigma=32.0, sigma_final=32.0)
    order = seeding.randint(participant_generators(0, P), 196, (64,))
    som_online.fit_online(som, X.expand(P, -1, -1), order)
    with quiet_native_output(), profile(activities=[ProfilerActivity.CPU]) as prof:
        som_online.fit_online(som, X.expand(P, -1, -1), order)
    ev = sorted(prof.key_averages(), key=lambda e: -e.self_cpu_time_total)
    total = sum(e.self_cpu_time_total for e in ev)
    parts = ", ".join(f"{e.key} {100 * e.self_cpu_time_total / total:.0f}%" for e in ev[:6])
    print(f"   where the online kernel's time goes ({P} maps, 64 steps): {parts}")


# ---------------------------------------------------------------------------------------- motor, robot
def bench_dmp(repeat, quick):
    try:
        import pydmps
    except ImportError:
        print("DMP: pydmps not installed (pip install pydmps): skipped")
        return None
    from neuroimagery.motor.dmp import DMP

    dmp = DMP()
    n, n_ref = (500, 20) if quick else (2000, 50)
    g = torch.Generator().manual_seed(0)
    goals = 0.3 * torch.randn(n, 7, generator=g)
    theta = torch.cat([goals, 50 * torch.randn(n, 28, generator=g)], 1)
    y0 = torch.zeros(n, 7)
    dmp.rollout(theta[:10], y0[:10])

    def ours():
        t = time.perf_counter()
        dmp.rollout(theta, y0, 2.0, 0.01)  # 200 steps
        return (time.perf_counter() - t) / n

    def ref():
        t = time.perf_counter()
        for i in range(n_ref):
            d = pydmps.DMPs_discrete(n_dmps=7, n_bfs=4, dt=0.005, y0=np.zeros(7), goal=theta[i, :7].numpy(),
                                     w=theta[i, 7:].reshape(7, 4).numpy())
            d.rollout()  # 200 steps
        return (time.perf_counter() - t) / n_ref

    res = side_by_side("dmp", ours, ref, repeat)
    line("DMP rollout, 7 joints, 200 steps", *res, "rollouts/s", "pydmps")
    zero = torch.cat([goals[:20], torch.zeros(20, 28)], 1)
    end = dmp.rollout(zero, y0[:20], 2.0, 0.01)[:, -1]
    err_ours = float((end - dmp.bounded_goals(goals[:20], y0[:20])).abs().max())
    errs = []
    for i in range(20):
        d = pydmps.DMPs_discrete(n_dmps=7, n_bfs=4, dt=0.005, y0=np.zeros(7), goal=goals[i].numpy(), w=np.zeros((7, 4)))
        errs.append(np.abs(d.rollout()[0][-1] - goals[i].numpy()).max())
    print(f"   check: without forcing both reach the goal: largest final error ours {err_ours:.1e}, "
          f"pydmps {max(errs):.1e} rad")
    return res


def bench_fk(repeat, quick):
    import tempfile

    import pybullet as pb

    from neuroimagery.core.native import quiet_native_output
    from neuroimagery.robot.kinematics import ARM_JOINTS, ArmKinematics, icub_urdf_text

    kin = ArmKinematics()
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(icub_urdf_text(keep_geometry=False))
    with quiet_native_output():
        cid = pb.connect(pb.DIRECT)
        body = pb.loadURDF(f.name, useFixedBase=True, flags=pb.URDF_MERGE_FIXED_LINKS, physicsClientId=cid)
    os.unlink(f.name)
    index = {pb.getJointInfo(body, i, physicsClientId=cid)[1].decode(): i for i in range(pb.getNumJoints(body, physicsClientId=cid))}
    joints = [index[j] for j in ARM_JOINTS]
    chest, hand = index["torso_yaw"], index["r_wrist_yaw"]
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    n, n_ref = (20_000, 500) if quick else (100_000, 2000)
    q = lo + (hi - lo) * torch.rand(n, 7, generator=torch.Generator().manual_seed(0))
    qn = q[:n_ref].double().numpy()
    kin(q[:10])
    poses = []

    def ours():
        t = time.perf_counter()
        with torch.no_grad():
            kin(q)
        return (time.perf_counter() - t) / n

    def ref():
        poses.clear()
        t = time.perf_counter()
        for row in qn:
            pb.resetJointStatesMultiDof(body, joints, [[v] for v in row], physicsClientId=cid)
            poses.append(pb.getLinkStates(body, [chest, hand], computeForwardKinematics=1, physicsClientId=cid))
        return (time.perf_counter() - t) / n_ref

    try:
        res = side_by_side("fk", ours, ref, repeat)
        line("FK iCub arm (hand pose)", *res, "configs/s", "pybullet")
        chest_T_hand = kin.arm.forward_kinematics(q[:n_ref]).get_matrix()
        err = 0.0
        for (c, h), T in zip(poses, chest_T_hand):
            pos, _ = pb.multiplyTransforms(*pb.invertTransform(c[4], c[5]), h[4], h[5])
            err = max(err, float(np.linalg.norm(np.array(pos) - T[:3, 3].numpy())))
        print(f"   check: largest hand position difference from pybullet over {n_ref} configurations {err:.1e} m")
    finally:
        pb.disconnect(cid)
    return res


def main():
    a = ARGS
    torch.set_num_threads(a.threads)
    repeat = a.repeat or (1 if a.quick else 3)
    P = a.participants
    t0 = time.perf_counter()
    print(f"torch {torch.__version__}, numpy {np.__version__}, {a.threads} thread(s) on both sides, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; medians of {repeat} back-to-back rounds")
    bench_hebbian(P, a.batch, repeat, a.quick)
    bench_delta(P, a.batch, repeat, a.quick)
    if bench_som(P, repeat, a.quick) is not None:
        som_profile(P)
    bench_dmp(repeat, a.quick)
    bench_fk(repeat, a.quick)
    total = time.perf_counter() - t0
    print(f"where the time went ({total:.0f} s): " + ", ".join(f"{k} {v:.1f} s" for k, v in SPENT.items()))
    print(f"load average at the end {os.getloadavg()[0]:.1f} (other work on the machine changes both sides alike)")


if __name__ == "__main__":
    sys.exit(main())
