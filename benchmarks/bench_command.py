"""The whole command of an experiment, timed from outside, and where its time goes.

    python benchmarks/bench_command.py exp4 [more overrides ...] [--repeat 1]

Runs ``python evaluate.py experiment=<exp> logger=none progress=false`` in a fresh process and a
temporary run directory (removed afterwards), then prints the wall time of the process and the
split that its ``summary.json`` records in ``runtime_s``: startup (interpreter, imports,
configuration), training, testing (evaluation less figures), figures, and the rest (writing the
report and files, exiting). Peak memory per phase comes from ``peak_rss_mb``. Say whether the
machine was idle: on shared cores the times depend on the other jobs.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from neuroimagery.core.arguments import ToolParser, check, count, run_tool
from neuroimagery.config import EXPERIMENTS

ROOT = Path(__file__).resolve().parents[1]


def run_once(exp: str, overrides: list[str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-command-") as tmp:
        cmd = [sys.executable, str(ROOT / "evaluate.py"), f"experiment={exp}", "logger=none", "progress=false",
               f"hydra.run.dir={tmp}", *overrides]
        before, t0 = os.times(), time.perf_counter()
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        wall, after = time.perf_counter() - t0, os.times()
        if done.returncode != 0:
            sys.exit(f"error: {' '.join(cmd[1:])} failed with status {done.returncode}:\n{done.stderr[-2000:]}")
        summary = json.loads((Path(tmp) / "summary.json").read_text())
    rt = summary.get("runtime_s", {})
    split = {"startup": rt.get("startup", 0.0), "train": rt.get("train", 0.0),
             "tests": rt.get("evaluate", 0.0) - rt.get("figures", 0.0), "figures": rt.get("figures", 0.0)}
    split["rest"] = wall - sum(split.values())
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return {"wall": wall, "cpu": cpu, "split": split, "runtime_s": rt, "peak_rss_mb": summary.get("peak_rss_mb", {})}


def main(argv=None) -> int:
    ap = ToolParser(description=__doc__.split("\n")[0])
    ap.add_argument("experiment", choices=EXPERIMENTS)
    ap.add_argument("overrides", nargs="*", help="more Hydra overrides, e.g. threads=1")
    ap.add_argument("--repeat", type=count, default=1)
    args = ap.parse_args(argv)
    check("--repeat", args.repeat, ge=1, le=100)
    for i in range(args.repeat):
        r = run_once(args.experiment, args.overrides)
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in r["split"].items())
        peaks = ", ".join(f"{k} {v} MiB" for k, v in r["peak_rss_mb"].items())
        print(f"{args.experiment} {' '.join(args.overrides)} run {i + 1}: {r['wall']:.1f} s wall = {parts}; "
              f"peak resident memory {peaks}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
