"""The rule for a quick preset's size (docs/choices.md, "Quick presets"), measured.

Runs the full protocol of an experiment at each seed, then candidates that halve every count the
preset shrinks (``--count KEY=FULL`` for each, e.g. ``experiment.quick.som_iterations=10000``),
each at every seed, and stops at the first candidate that is not admissible: an effect that holds
in the full run (expected sign, p (Holm) < 0.05) changes sign, or a headline rate (correct,
rotation success of each test and condition) moves more than 15 points from the full run's. Each
run is a separate process at ``threads=1``; its CPU time (user + system, start-up included) and
the run's own train and test times are printed. Usage:

    python benchmarks/quick_presets.py exp2 --count experiment.quick.som_iterations=10000 [--seeds 0 1 2 3 4]
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


def run(exp: str, seed: int, out: Path, extra: list[str]) -> dict:
    """One evaluate.py run; its summary with the CPU seconds of the process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), f"experiment={exp}", f"seed={seed}", "threads=1",
                        "progress=false", "logger=none", f"hydra.run.dir={out}", *extra], cwd=ROOT, env=env,
                       capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"error: {exp} seed {seed} {' '.join(extra)} failed: {p.stderr.strip()[-400:]}")
    s = json.loads((out / "summary.json").read_text())
    s["cpu_s"] = round(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, 1)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("experiment")
    ap.add_argument("--count", action="append", required=True, help="KEY=FULL: a count the preset shrinks")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--extra", nargs="*", default=[], help="settings of every run")
    ap.add_argument("--start", type=int, default=2, help="the first candidate's divisor (2: full / 2)")
    ap.add_argument("--candidate-preset", default="quick",
                    help="the preset of the candidate runs ('full' where the counts are full-protocol keys)")
    a = ap.parse_args()
    counts = {k: int(v) for k, v in (c.split("=") for c in a.count)}
    tmp = Path(tempfile.mkdtemp(prefix="quick_presets_"))
    full = {}
    for seed in a.seeds:
        full[seed] = run(a.experiment, seed, tmp / f"full{seed}", a.extra)
        t = full[seed]["runtime_s"]
        print(f"full seed {seed}: cpu {full[seed]['cpu_s']} s, train {t.get('train')} s, test {t.get('evaluate')} s; "
              + ", ".join(f"{k} {100 * v:.1f} %" for k, v in rates(full[seed]).items()), flush=True)
    factor = a.start
    while True:
        sizes = {k: max(1, v // factor) for k, v in counts.items()}
        over = [f"preset={a.candidate_preset}"] + [f"{k}={v}" for k, v in sizes.items()]
        bad = []
        for seed in a.seeds:
            s = run(a.experiment, seed, tmp / f"q{factor}_{seed}", a.extra + over)
            t = s["runtime_s"]
            why = admissible(full[seed], s)
            bad += why
            print(f"1/{factor} {sizes} seed {seed}: cpu {s['cpu_s']} s (full {full[seed]['cpu_s']} s), train "
                  f"{t.get('train')} s, test {t.get('evaluate')} s; " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in rates(s).items())
                  + (f"; NOT admissible: {'; '.join(why)}" if why else ""), flush=True)
        if bad or all(v == 1 for v in sizes.values()):
            print(f"first candidate not admissible: 1/{factor}; the preset is 1/{factor // 2}" if bad else "every count at 1")
            break
        factor *= 2


if __name__ == "__main__":
    main()
