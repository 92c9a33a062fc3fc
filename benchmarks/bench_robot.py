"""Speed of the tool-use world and motor primitives (not a test).

    python benchmarks/bench_robot.py

Prints: FK error against pybullet; rollouts/s for K = 10 babbling samples from each posture with and
without the FK filter, and the share of time in physics, rendering and tensors; batched DMP rollouts/s
against pydmps one rollout at a time (pydmps is imported lazily; `pip install pydmps`).
"""
from __future__ import annotations

import json
import time

import numpy as np
import torch

from neuroimagery.core.arguments import ToolParser, run_tool


def bench_world(reps: int = 3) -> dict:
    """Rollouts/s of K = 10 babbling samples from each posture, one camera image per batch.

    The kinematic rake drive: imposed pose, far steps skipped with the filter.
    """
    from neuroimagery.robot.config import WorldConfig
    from neuroimagery.robot.movements import MovementConfig, goal_noise, random_primitives, trajectories, world_dmp
    from neuroimagery.robot.world import ToolWorld

    out = {}
    dmp = world_dmp()
    for drive in ("kinematic",):
        with ToolWorld(WorldConfig()) as w:
            cfg = MovementConfig(dt=w.cfg.control_dt)
            for use_filter in (False, True):
                g = torch.Generator().manual_seed(0)
                w.timing.update(physics_s=0.0, tensor_s=0.0, render_s=0.0)
                w.steps_simulated = w.steps_total = 0
                n, t0, c0 = 0, time.perf_counter(), time.process_time()
                for _ in range(reps):
                    for k in range(1, 5):
                        t1 = time.perf_counter()
                        theta = goal_noise(w, dmp, random_primitives(w, dmp, 10, cfg, g), g)
                        traj = trajectories(w, dmp, theta, w.initial_posture(k), cfg)
                        w.timing["tensor_s"] += time.perf_counter() - t1
                        w.rollout(traj, k, None, use_filter=use_filter)
                        w.observe()  # one camera image per batch, as a learner would look
                        n += 10
                total = time.perf_counter() - t0
                cpu = time.process_time() - c0
                key = f"{drive}_{'with' if use_filter else 'without'}_filter"
                out[key] = {
                    "rollouts_per_s": round(n / total, 1),
                    "rollouts_per_cpu_s": round(n / cpu, 1),  # less sensitive to other jobs on the cores
                    "share_physics_loop": round(w.timing["physics_s"] / total, 3),
                    "share_render": round(w.timing["render_s"] / total, 3),
                    "share_tensors": round(w.timing["tensor_s"] / total, 3),
                }
                out[key]["share_of_steps_simulated"] = round(w.steps_simulated / max(w.steps_total, 1), 3)
            # raw physics stepping of the rake/toy/table scene
            w.reset(1)
            t0 = time.perf_counter()
            for _ in range(2000):
                w.client.stepSimulation()
            out[f"{drive}_physics_steps_per_s"] = round(2000 / (time.perf_counter() - t0))
    return out


def bench_dmp(n: int = 2000, n_pydmps: int = 100) -> dict:
    from neuroimagery.motor.dmp import DMP

    dmp = DMP()
    theta = torch.cat([torch.randn(n, 7), 100 * torch.randn(n, 28)], 1)
    y0 = torch.zeros(n, 7)
    dmp.rollout(theta[:10], y0[:10])
    t0 = time.perf_counter()
    dmp.rollout(theta, y0, 2.0, 0.01)
    ours = n / (time.perf_counter() - t0)
    res = {"torch_batched_rollouts_per_s": ours}
    try:
        import pydmps  # lazily: benchmark-only dependency
    except ImportError:
        res["pydmps"] = "not installed"
        return res
    t0 = time.perf_counter()
    for i in range(n_pydmps):
        d = pydmps.DMPs_discrete(n_dmps=7, n_bfs=4, dt=0.005, y0=np.zeros(7), goal=theta[i, :7].numpy(),
                                 w=theta[i, 7:].reshape(7, 4).numpy())
        d.rollout()
    theirs = n_pydmps / (time.perf_counter() - t0)
    res.update(pydmps_rollouts_per_s=theirs, speedup=ours / theirs)
    return res


def bench_fk() -> dict:
    from neuroimagery.robot.kinematics import ArmKinematics

    kin = ArmKinematics()
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    q = lo + (hi - lo) * torch.rand(100_000, 7)
    kin(q[:10])
    t0 = time.perf_counter()
    with torch.no_grad():
        kin(q)
    return {"fk_configs_per_s": len(q) / (time.perf_counter() - t0)}


def main(argv=None) -> None:
    ToolParser(description=__doc__.split("\n")[0]).parse_args(argv)
    res = {"fk": bench_fk(), "dmp": bench_dmp(), "world": bench_world()}
    print(json.dumps(res, indent=2), flush=True)


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
