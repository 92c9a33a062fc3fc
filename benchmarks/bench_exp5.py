"""Benchmark of Experiment 5: individuals per minute and where the time goes.

    python benchmarks/bench_exp5.py [--repetitions 1] [--situation far] [--standin]

Runs whole tasks (one repetition x one situation: skill acquisition, then every HP1/HP2
individual built on that library, both strategies) in this process and prints the cost split:
physics rollouts, eye renders, and the rest (DMP integration, C1-C4 updates, bookkeeping).
An individual = one robot (repetition x situation) of one group, tested as reactive and planning.
Wall and CPU time are both printed (on shared cores the wall time depends on the other jobs);
loading the robot once per worker process is timed apart, since a run pays it once per worker.
Peak memory: the process's peak resident set while the tasks ran (neuroimagery/core/memory.py).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from neuroimagery.core.arguments import ToolParser, check, check_size, count, run_tool, seed

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = ToolParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repetitions", type=count, default=1)
    ap.add_argument("--allow-large", action="store_true", help="allow more than 100 repetitions")
    ap.add_argument("--situation", default="far", choices=["behind", "far"])
    ap.add_argument("--standin", action="store_true", help="use the tests' 2-D stand-in world (not the robot)")
    ap.add_argument("--seed", type=seed, default=0)
    args = ap.parse_args(argv)
    check("--repetitions", args.repetitions, ge=1)
    check_size("--repetitions", args.repetitions, 100, args.allow_large)

    from neuroimagery.core import memory
    from neuroimagery.experiments.exp5 import protocol as exp5, config as exp5_config, task as exp5_task

    kw = {}
    if args.standin:
        sys.path.insert(0, str(ROOT / "tests"))
        kw["world"] = exp5_config.WorldParams(environment="support_tool_env:StandInToolEnv")
    e = exp5.Exp5Config(situations=[args.situation], **kw)
    totals: dict[str, float] = {}
    individuals = 0
    t_load, c_load = time.perf_counter(), time.process_time()
    env = exp5_task._task_environment(e)  # the world is built once per worker process and reused by its tasks
    world_timing = getattr(getattr(env, "world", None), "timing", None)  # pybullet's own share, all phases
    world0 = dict(world_timing or {})
    t_load, c_load = time.perf_counter() - t_load, time.process_time() - c_load
    print(f"loading the world (once per worker): wall {t_load:.1f} s, CPU {c_load:.1f} s")
    memory.reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    for r in range(args.repetitions):
        task = dict(repetition=r, situations=[args.situation], key=f"bench{r}")
        res = exp5.run_task(e, args.seed, task)
        individuals += len(exp5.groups(e))
        for k, v in res["timing"].items():
            totals[k] = totals.get(k, 0.0) + float(v)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = memory.peak_rss_mb()
    print(f"tasks {args.repetitions}, individuals {individuals} (each tested reactive + planning), "
          f"wall {wall:.1f} s, CPU {cpu:.1f} s; peak resident memory of this process {peak} MiB "
          f"(the world, loaded before, included; parallel workers are separate processes)")
    print(f"individuals per minute (one process): {60 * individuals / wall:.2f} wall, "
          f"{60 * individuals / cpu:.2f} per CPU-minute")
    acq = totals.get("acquisition_s", 0.0)
    print(f"skill acquisition (Fig. 7.5): {acq:.1f} s ({100 * acq / wall:.0f} %), "
          f"{totals.get('explore_rollouts', 0):.0f} exploration + {totals.get('learn_rollouts', 0):.0f} PI^BB rollouts")
    print(f"action sequencing + brain replay (Fig. 7.6): {wall - acq:.1f} s ({100 * (wall - acq) / wall:.0f} %)")
    for k in ("rollout_s", "render_s"):
        if k in totals:
            n = totals.get(k.replace("_s", "s"), 0)
            print(f"  {k:10s} {totals[k]:8.1f} s  ({100 * totals[k] / wall:.0f} %, {n:.0f} {k.replace('_s', 's')})")
    if world_timing is not None:
        phys = world_timing["physics_s"] - world0.get("physics_s", 0.0)
        rend = world_timing["render_s"] - world0.get("render_s", 0.0)
        print(f"inside the world, acquisition and sequencing together: simulated rollouts (pybullet steps and "
              f"contact bookkeeping) {phys:.1f} s ({100 * phys / wall:.0f} %), eye renders (pybullet camera) "
              f"{rend:.1f} s ({100 * rend / wall:.0f} %), together {phys + rend:.1f} s of {wall:.1f} s")
    full = 30 * 2 * len(exp5.groups(e))
    print(f"full HP1 + HP2 ({full} individuals) estimate on 2 free cores: "
          f"{full / (60 * individuals / cpu) / 2:.1f} min (CPU-bound), {full / (60 * individuals / wall) / 2:.1f} min "
          f"at this run's wall speed")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
