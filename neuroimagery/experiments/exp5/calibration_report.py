"""The calibration's history as markdown (``exp5.calibrate --stage report``): the candidates
rejected, screened and confirmed, the CPU-seconds spent, the front of W3 against W4 and the
Table 7.1 cells, the best by the rule of docs/world_calibration.md, beside the present world."""
from __future__ import annotations

from collections import Counter

from .candidate import pareto, rank_key


def _row(name: str, m: dict) -> str:
    return (f"| {name} | {m['w1']} | {m['w2']} | {m['w1'] + m['w2']} | {m['pull_alone']} of {m['with_pull']} "
            f"({m['w3']:.0%}) | {m['routes']} of {m['libraries']} ({m['w4']:.0%}) | "
            f"{'yes' if m['w3'] < 0.05 and m['w4'] > 0.5 else 'no'} |\n")


HEAD = ("| candidate | W1 events (of 24) | W2 skills (of 24) | W1 + W2 | W3 pull alone from 4 | W4 move-then-pull "
        "| W3 and W4 met |\n|---|---|---|---|---|---|---|\n")


def screen_sizes(study, trial) -> dict:
    """The sizes ``trial`` was screened at: its own record, else the journal's first sizes (a screen
    before the fourth amendment, docs/world_calibration.md)."""
    history = study.user_attrs.get("sizes_history") or [dict(sizes=study.user_attrs.get("sizes"))]
    return trial.user_attrs.get("sizes") or history[0]["sizes"]


def screened_at(study, sizes: dict) -> list:
    """The trials screened at ``sizes`` (the front and the rule compare only these)."""
    return [t for t in study.get_trials(deepcopy=False)
            if t.user_attrs.get("stage") == "screened" and screen_sizes(study, t) == sizes]


def report(study) -> str:
    trials = study.get_trials(deepcopy=False)
    stages = Counter(t.user_attrs.get("stage", str(t.state).split(".")[-1].lower()) for t in trials)
    cpu = sum(t.user_attrs.get("cpu_s", 0.0) for t in trials)
    attrs = study.user_attrs
    extra = sum(v.get("cpu_s", 0.0) for k, v in attrs.items() if k.startswith("confirmed_") or k == "baseline")
    reasons = Counter((t.user_attrs.get("reasons") or ["?"])[0].split(":")[0] for t in trials
                      if t.user_attrs.get("stage") == "rejected")
    screened = [(f"trial {t.number}", t.user_attrs["measures"]) for t in screened_at(study, attrs.get("sizes"))]
    former = [t for t in trials if t.user_attrs.get("stage") == "screened" and screen_sizes(study, t) != attrs.get("sizes")]
    out = [f"## The search: {len(trials)} candidates ({stages.get('rejected', 0)} rejected by stage 1, "
           f"{stages.get('screened', 0)} screened, {stages.get('fail', 0)} stopped, {stages.get('running', 0)} running, "
           f"{stages.get('waiting', 0)} waiting), "
           f"{sum(1 for k in attrs if k.startswith('confirmed_') and k != 'confirmed_baseline')} confirmed; "
           f"{cpu + extra:.0f} CPU-s spent ({cpu:.0f} in trials)\n",
           f"Screening sizes: {attrs.get('sizes')}"
           + "".join(f"; before trial {h['before_trial']}: {h['sizes']}" for h in attrs.get("sizes_history", [])) + ".\n",
           "Stage 1 rejections by first reason: " + ", ".join(f"{k} {v}" for k, v in reasons.most_common()) + "\n"]
    if screened or "baseline" in attrs:
        out.append("\n### Screened (calibration seed 100): the front by the rule, the present world beside it\n\n" + HEAD)
        if "baseline" in attrs:
            out.append(_row("present world", attrs["baseline"]))
        out += [_row(n, m) for n, m in pareto(screened)]
        if screened:
            best = min(screened, key=lambda nm: rank_key(nm[1]))
            out.append(f"\nBest screened by the rule: {best[0]}.\n")
    if former:
        out.append("\n### Screened at former sizes (not in the front)\n\n" + HEAD)
        out += [_row(f"trial {t.number} ({screen_sizes(study, t)})", t.user_attrs["measures"]) for t in former]
    confirmed = [(k[len("confirmed_"):], v) for k, v in attrs.items() if k.startswith("confirmed_")]
    if confirmed:
        out.append("\n### Confirmed at acceptance size (calibration seeds)\n\n" + HEAD)
        out += [_row("present world" if n == "baseline" else f"trial {n}", m)
                for n, m in sorted(confirmed, key=lambda nm: rank_key(nm[1]))]
    return "".join(out)
