"""The rule for a quick preset's size (docs/choices.md, "Quick presets"), measured: each seed's
quick run against the full run of the same seed.

Each run is a separate ``evaluate.py`` process at ``threads=1``; its CPU time (user + system) is
measured whole and with start-up aside (the CPU of the same command stopped by ``--cfg job``
after composing its configuration, i.e. the interpreter and the imports, is subtracted). Printed
per seed: both runs' CPU seconds and headline rates, and what breaks the rule's claims (an
effect that holds in the full run changing direction, a rate more than 15 points off, the quick
run above max(full / 4, 30 s) of CPU, start-up aside). Usage:

    python benchmarks/quick_presets.py exp2 [--seeds 0 1 2 3 4] [--extra KEY=VALUE ...]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RATES = ("correct_rate", "rotation_success_rate")


def _cpu(args: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), *args], cwd=ROOT, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return p, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def run(exp: str, seed: int, out: Path, extra: list[str]) -> dict:
    """One evaluate.py run; its summary with the CPU seconds of the process (``cpu_s``) and with
    start-up aside (``cpu_work_s``)."""
    args = [f"experiment={exp}", f"seed={seed}", "threads=1", "progress=false", "logger=none", f"hydra.run.dir={out}", *extra]
    p, cpu = _cpu(args)
    if p.returncode != 0:
        raise SystemExit(f"error: {exp} seed {seed} {' '.join(extra)} failed: {p.stderr.strip()[-400:]}")
    _, startup = _cpu(args + ["--cfg", "job"])
    s = json.loads((out / "summary.json").read_text())
    s["cpu_s"], s["cpu_startup_s"], s["cpu_work_s"] = round(cpu, 1), round(startup, 1), round(cpu - startup, 1)
    return s


def rates(s: dict) -> dict:
    return {f"{t}:{k}": v[k] for t, v in s.get("tests", {}).items() for k in RATES if isinstance(v.get(k), (int, float))}


def admissible(full: dict, cand: dict) -> list[str]:
    """Why ``cand`` is not admissible against ``full`` (empty when it is)."""
    why = []
    signs = {e["effect"]: e["value"] for e in cand.get("effects", [])}
    for e in full.get("effects", []):
        if e.get("holds") and e["expected"] in (">0", "<0"):
            v = signs.get(e["effect"])
            if v is None or (v > 0) != (e["expected"] == ">0"):
                why.append(f"effect '{e['effect']}' {v}")
    fr, cr = rates(full), rates(cand)
    why += [f"{k} {100 * cr.get(k, float('nan')):.1f} % vs {100 * v:.1f} %" for k, v in fr.items()
            if not abs(cr.get(k, float("nan")) - v) <= 0.15 + 1e-9]  # 15 points exactly is within (not float rounding)
    return why


def over_time(full: dict, quick: dict) -> list[str]:
    """The time bound of the rule: the quick run's CPU (start-up aside) at most max(full / 4, 30 s)."""
    bound = max(full["cpu_work_s"] / 4, 30.0)
    return [] if quick["cpu_work_s"] <= bound else [f"CPU {quick['cpu_work_s']} s > {bound:.1f} s"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("experiment")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--extra", nargs="*", default=[], help="settings of every run")
    ap.add_argument("--out", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    a = ap.parse_args()
    tmp = a.out or Path(tempfile.mkdtemp(prefix="quick_presets_"))
    for seed in a.seeds:
        full = run(a.experiment, seed, tmp / f"full{seed}", a.extra)
        quick = run(a.experiment, seed, tmp / f"quick{seed}", a.extra + ["preset=quick"])
        why = admissible(full, quick) + over_time(full, quick)
        for name, s in (("full", full), ("quick", quick)):
            print(f"{a.experiment} seed {seed} {name}: {s['participants']} participants, CPU {s['cpu_s']} s "
                  f"(start-up aside {s['cpu_work_s']} s); " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in rates(s).items())
                  + "; effects holding: " + ", ".join(f"{e['effect']} {e['value']:.3g}" for e in s.get("effects", [])
                                                     if e.get("holds")), flush=True)
        print(f"{a.experiment} seed {seed}: " + ("within the rule's claims" if not why else "MISS: " + "; ".join(why)),
              flush=True)


if __name__ == "__main__":
    main()
