"""Thread use on a busy machine: an experiment's wall time with the default thread setting
(``threads=0``: the cores other work leaves free, measured at start-up) and with ``threads=2``, on an idle machine and while another
process (a two-thread torch loop) keeps the cores busy. Prints each time and the default's ratio to
the best setting of each case; the trial rows must not depend on the thread count.

    python benchmarks/bench_threads.py [--experiment exp4] [--preset quick|full]

Runs one thing at a time; the machine should be otherwise idle.
"""
from __future__ import annotations

import filecmp
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from neuroimagery.core.arguments import ToolParser, run_tool
from neuroimagery.config import EXPERIMENTS

ROOT = Path(__file__).resolve().parents[1]
LOAD = ("import torch, time\ntorch.set_num_threads(2)\na = torch.rand(400, 400)\nt0 = time.time()\n"
        "while time.time() - t0 < 3600:\n    a = torch.tanh(a @ a)\n")


def run(experiment: str, preset: str, threads: int, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, str(ROOT / "evaluate.py"), f"experiment={experiment}", f"preset={preset}",
                    f"threads={threads}", "logger=none", "progress=false", f"hydra.run.dir={out}"],
                   check=True, capture_output=True, cwd=ROOT)
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = ToolParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--experiment", default="exp4", choices=EXPERIMENTS)
    ap.add_argument("--preset", default="quick", choices=("quick", "full"))
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="bench_threads-"))
    rows = []
    for case in ("idle", "busy"):
        load = subprocess.Popen([sys.executable, "-c", LOAD]) if case == "busy" else None
        try:
            times = {t: run(args.experiment, args.preset, t, tmp / f"{case}_t{t}") for t in (0, 2)}
        finally:
            if load is not None:
                load.kill()
                load.wait()
        rows.append((case, times[0], times[2], times[0] / min(times.values())))
    same = all(filecmp.cmp(tmp / "idle_t0" / "trials.csv", tmp / f"{c}_t{t}" / "trials.csv", shallow=False)
               for c in ("idle", "busy") for t in (0, 2))
    print(f"{args.experiment} preset={args.preset}: wall seconds")
    print(f"{'machine':8} {'threads=0 (auto)':>20} {'threads=2':>10} {'default / best':>15}")
    for case, t0, t2, ratio in rows:
        print(f"{case:8} {t0:20.1f} {t2:10.1f} {ratio:15.2f}")
    print("trial rows identical at every setting:", same)


if __name__ == "__main__":
    raise SystemExit(run_tool(main))
