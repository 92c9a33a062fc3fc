"""The speed goals of docs/performance.md, each measured from outside in a fresh process and printed
with its ratio to the goal (under 1.00 meets it).

    python benchmarks/goals.py [refusal startup exp4 exp12 exp6 exp5 suite] [--repeat 1]

- ``refusal``: ``evaluate.py experiment=exp4 participants=-3`` answers (goal 1 s wall);
- ``startup``: Exp 4's ``runtime_s.startup``, process start to training (goal 2 s);
- ``exp4``: Experiment 4, full protocol (goal 10 s wall);
- ``exp12``: Experiments 1 and 2, full protocol, one after the other (goal 30 s wall);
- ``exp6``: Experiment 6, full protocol (goal 90 s wall);
- ``exp5``: one seed of Experiment 5, full protocol (goal 300 CPU-s, the run's processes summed);
- ``suite``: the default test suite, ``python -m pytest -q`` (goal 360 s wall).

With no names: every goal but ``exp5`` and ``suite`` (minutes each). Wall times hold on two idle
cores only: say whether the machine was idle; the CPU-seconds (the process and its children) are
the steadier number on shared cores.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from neuroimagery.core.arguments import ToolParser, check, count, run_tool

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_command import run_once  # noqa: E402  (the whole command, timed from outside)
RUN = [sys.executable, str(ROOT / "evaluate.py"), "logger=none", "progress=false"]
GOALS = {"refusal": 1.0, "startup": 2.0, "exp4": 10.0, "exp12": 30.0, "exp6": 90.0, "exp5": 300.0, "suite": 360.0}
UNIT = {"exp5": "CPU-s"}
DEFAULT = ("refusal", "startup", "exp4", "exp12", "exp6")


def timed(cmd: list[str], ok=(0,)) -> tuple[float, float, subprocess.CompletedProcess]:
    """Wall and CPU seconds (user + system of the child processes) of ``cmd``."""
    before = os.times()
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = os.times()
    if done.returncode not in ok:
        sys.exit(f"error: {' '.join(cmd[1:])} failed with status {done.returncode}:\n{done.stderr[-2000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return wall, cpu, done


def experiment(names: list[str]) -> tuple[float, float, dict]:
    """The experiments ``names`` at the full protocol, one after the other (``bench_command.run_once``:
    each in its own run directory, removed afterwards): wall, CPU and the last run's ``runtime_s``."""
    runs = [run_once(name, []) for name in names]
    return sum(r["wall"] for r in runs), sum(r["cpu"] for r in runs), runs[-1]["runtime_s"]


def measure(goal: str) -> tuple[float, str]:
    """The measured value of ``goal`` (in its unit) and a line of detail."""
    if goal == "refusal":
        wall, cpu, _ = timed([*RUN, "experiment=exp4", "participants=-3"], ok=(2,))
        return wall, f"CPU {cpu:.2f} s"
    if goal == "startup":
        _, _, rt = experiment(["exp4"])
        return rt.get("startup", float("nan")), "runtime_s.startup of a full Exp 4 run"
    if goal in ("exp4", "exp6", "exp12"):
        wall, cpu, rt = experiment(["exp1", "exp2"] if goal == "exp12" else [goal])
        split = ", ".join(f"{k} {v:.1f}" for k, v in rt.items())
        return wall, f"CPU {cpu:.1f} s" + (f"; runtime_s: {split}" if goal != "exp12" else "")
    if goal == "exp5":
        wall, cpu, _ = experiment(["exp5"])
        return cpu, f"wall {wall:.0f} s"
    wall, cpu, done = timed([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"])
    return wall, f"CPU {cpu:.0f} s; {done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ''}"


def main(argv=None) -> int:
    ap = ToolParser(description=__doc__.split("\n")[0])
    ap.add_argument("goals", nargs="*", choices=list(GOALS), help="which goals (default: all but exp5 and suite)")
    ap.add_argument("--repeat", type=count, default=1)
    args = ap.parse_args(argv)
    check("--repeat", args.repeat, ge=1, le=20)
    for goal in args.goals or DEFAULT:
        for i in range(args.repeat):
            value, detail = measure(goal)
            unit = UNIT.get(goal, "s")
            print(f"{goal:8s} {value:8.1f} {unit:5s} goal {GOALS[goal]:6.0f} {unit:5s} ratio {value / GOALS[goal]:5.2f}"
                  f"  ({detail})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
