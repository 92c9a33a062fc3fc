"""The report of Experiment 5 (report.md): success tables beside the thesis, the checks of its claims,
how the tool-far successes happen, Table 7.1 as discovered, what differs from the thesis, the cost."""
from __future__ import annotations

import numpy as np

from ...analysis.report import Report, reproducibility_note
from ...analysis.robots import ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE
from ...models.tool_use import EVENTS, N_POSTURES, SKILL_LETTERS
from .config import THESIS, THESIS_TABLE_7_1
from .summary import group_rates

STRATEGIES = ("reactive", "planning")


def fmt(v, pct: bool = False) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "n/a"
    return f"{100 * v:.0f} %" if pct else f"{v:.2f}"


def group_table(e, h: str, cell) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the success table of hypothesis ``h`` (one row per group; per situation
    the reactive and planning cells from ``cell(h, level, situation, strategy)``, then the thesis)."""
    levels, ages, xl = ((e.hp1_levels, e.hp1_ages, "IM detectors") if h == "hp1"
                        else (e.hp2_trials, e.hp2_ages, "training trials"))
    rows = []
    for lv, age in zip(levels, ages):
        row = [str(lv), str(age)]
        for sit in e.situations:
            row += [cell(h, lv, sit, strat) for strat in STRATEGIES]
            th = THESIS[h][sit].get(lv)
            row.append("-" if th is None else f"~{100 * th:.0f} %")
        rows.append(row)
    head = [xl, "age (months)"]
    for sit in e.situations:
        head += [f"{sit} reactive", f"{sit} planning", f"{sit} thesis"]
    return head, rows


def write_report(cfg, run, summary: dict) -> None:
    e = cfg.experiment
    rate = group_rates(summary["groups"])
    rep = Report("Experiment 5: tool-use development in infant robots")
    env_note = ("the pybullet rake-and-toy world (`robot.world.ToolWorld`)" if e.world.environment == "robot"
                else f"`{e.world.environment}` (a STAND-IN environment, not the thesis's robot: these numbers are not results)")
    rep.p(f"{summary['repetitions']} repetitions per group and situation, each individual tested as a reactive and "
          f"as a planning child; world: {env_note}. Preset `{cfg.preset}`.")
    _success_tables(rep, e, run, summary, rate)
    _checks(rep, e, summary, rate)
    if summary.get("effects"):
        rep.h("Effects, the robot as the unit")
        rep.effects(summary["effects"], ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE)
    _routes(rep, e, summary)
    _mechanism(rep, e, summary)
    _table_7_1(rep, summary)
    for key, cap in (("situations", "The eye's view of the four initial situations and their PC maps"),
                     ("filmstrip", "One retrieval by a planning child: imagined outcome (C3) above the real scene")):
        if key in summary.get("figures", {}):
            rep.figure(run.root / summary["figures"][key], cap, run.root)
    _differences(rep, e, summary)
    _cost(rep, summary)
    rep.p(reproducibility_note(cfg.seed))
    rep.write(run.report_path)


def _success_tables(rep: Report, e, run, summary: dict, rate: dict) -> None:
    def cell(h, lv, sit, strat):
        r = rate.get((h, lv, sit, strat))
        return "-" if r is None else f"{100 * r:.0f} %"

    for h, xl in (("hp1", "IM detectors"), ("hp2", "training trials")):
        rep.h(f"{h.upper()}: success rate by {xl}")
        rep.table(*group_table(e, h, cell))
        key = "fig_7_9" if h == "hp1" else "fig_7_10"
        if key in summary.get("figures", {}):
            rep.figure(run.root / summary["figures"][key], f"Redrawn Fig. {'7.9' if h == 'hp1' else '7.10'}", run.root)


def _checks(rep: Report, e, summary: dict, rate: dict) -> None:
    c = summary["checks"]
    rep.h("Checks against the thesis")
    far2 = np.mean([rate.get(("hp1", e.hp1_levels[0], "far", s)) or 0 for s in STRATEGIES])
    far6 = np.mean([rate.get(("hp1", e.hp1_levels[-1], "far", s)) or 0 for s in STRATEGIES])
    beh = [rate.get(("hp1", k, "behind", s)) for k in e.hp1_levels for s in STRATEGIES]
    beh = [b for b in beh if b is not None]
    rep.bullets([
        f"HP1 tool behind toy: {100 * min(beh):.0f}-{100 * max(beh):.0f} % over ages and strategies (thesis ~90 %, 100 % at 14 months)." if beh else "HP1 behind: not run",
        f"HP1 tool far from toy: {100 * far2:.0f} % at {e.hp1_ages[0]} months, {100 * far6:.0f} % at {e.hp1_ages[-1]} months "
        f"(thesis ~0 % and ~60 %).",
        f"Spearman's rho of far-from-toy success over the HP1 groups: pooled {fmt(c.get('hp1_far_spearman_pooled'))}, "
        f"reactive {fmt(c.get('hp1_far_spearman_reactive'))}, planning {fmt(c.get('hp1_far_spearman_planning'))} (target >= 0.8).",
        f"Largest reactive-planning difference over all groups: {fmt(c.get('reactive_planning_max_abs_diff'), pct=True)} "
        "(thesis: the two systems look identical).",
    ])
    claims = summary.get("claims") or []
    if claims:
        n = min(g["n"] for g in summary["groups"])
        rep.p(f"The must-show claims (thresholds in `experiments.exp5.thesis_claims`): "
              f"{sum(c['holds'] for c in claims)} of {len(claims)} hold. With {n} robots per group one robot "
              f"is {100 / n:.1f} points of a rate, and a rate near 30 % has a binomial standard error of "
              f"{100 * (0.21 / n) ** 0.5:.0f} points, so claims that compare single groups can change with the seed (pool runs of several seeds "
              f"with `python -m neuroimagery.app.pool`).")
        rep.table(["claim", "this run", "holds"], [[c["claim"], c["value"], "yes" if c["holds"] else "**no**"] for c in claims])


def _routes(rep: Report, e, summary: dict) -> None:
    routes = [r for r in summary.get("routes", []) if r["hypothesis"] == "hp1"]
    if not routes:
        return
    rep.h("How the tool-far successes happen (HP1)")
    rep.p("Each successful tool-far test sorted by its moves: one pull alone; other moves and then a pull (the "
          "thesis's route, Fig. 7.8: a move that brings the tool behind the toy, then P); or a last move that is "
          "not a pull (touch or an interaction primitive that itself brought the toy into reach). "
          "summary.json `routes` holds the same counts for every tool-far group.")
    has = {"avail": all("available" in r for r in routes), "imag": all("imagined" in r for r in routes),
           "still": any(r.get("no_move") for r in routes)}
    if has["avail"]:
        rep.p("The next column counts the robots for which the world holds a retrieval of one or two moves "
              "with their primitives (individuals.csv `routes_1`, `routes_2`), whether or not they find it: "
              "what the world offers, against what the learners make of it.")
    if has["imag"]:
        rep.p("The last column counts the robots whose mental images (C3 run backwards from the far "
              "situation) show the toy in reach after one or two moves (`imagined_1`, `imagined_2`), and in "
              "brackets those with such an imagined route that also works in the world (`imagined_true`): "
              "what a planning child can learn in mind.")
    if has["still"]:
        rep.p(f"With `sequencing.active_threshold: {e.sequencing.active_threshold}` a child moves only a primitive whose PMC activity "
              "(C1 + C4) exceeds it (Fig. 7.6 draws among the *active* PMC units); the column \"did not move\" counts "
              "the tests, reactive / planning, in which nothing was active in the far situation.")
    by = {(r["level"], r["strategy"]): r for r in routes}
    rows = [_route_row(by, k, age, has) for k, age in zip(e.hp1_levels, e.hp1_ages)]
    rep.table(["IM detectors", "age (months)", "reactive: successes: pull / moves then pull / other",
               "planning: successes: pull / moves then pull / other"]
              + (["robots with a 1-2 move retrieval"] if has["avail"] else [])
              + (["robots with an imagined 1-2 move retrieval (true)"] if has["imag"] else [])
              + (["did not move, reactive / planning"] if has["still"] else []), rows)


def _route_row(by: dict, k, age, has: dict) -> list:
    row = [k, age]
    for strat in STRATEGIES:
        r = by.get((k, strat))
        row.append("-" if r is None else f"{r['successes']} of {r['n']}: {r['pull']} / {r['moves_then_pull']} / {r['other']}")
    r = by.get((k, "reactive")) or by.get((k, "planning"))
    if has["avail"]:
        row.append("-" if r is None else f"{r['available']} of {r['n']}")
    if has["imag"]:
        row.append("-" if r is None else f"{r['imagined']} ({r['imagined_true']}) of {r['n']}")
    if has["still"]:
        row.append(" / ".join(str(by[(k, st)].get("no_move", 0)) if (k, st) in by else "-" for st in STRATEGIES))
    return row


def _mechanism(rep: Report, e, summary: dict) -> None:
    mech = summary.get("mechanism") or {}
    if not mech:
        return
    rep.h("The mechanism of the tool-far test")
    rep.p("Table 7.1 forbids a retrieving pull from posture 4; Fig. 7.8 solves the tool-far situation by an "
          "interaction skill that brings the tool behind the toy, then a pull. Counts over the tool-far robots "
          "(summary.json `mechanism`).")
    labels = {"far_single_pull": ("a learnt pull alone retrieves from posture 4", "retrieve", "robots"),
              "far_interaction_from_4": ("an interaction skill learnt elsewhere works from posture 4", "carry_over",
                                         "robots"),
              "oldest_far_moves_then_pull": (f"tool-far successes at {e.hp1_ages[-1]} months that move first, "
                                             "then pull", "moves_then_pull", "successes")}
    rep.table(["check", "count", "share"],
              [[labels[k][0], f"{v[labels[k][1]]} of {v[labels[k][2]]}", fmt(v["share"], pct=True)]
               for k, v in mech.items() if k in labels])


def _table_7_1(rep: Report, summary: dict) -> None:
    rep.h("Table 7.1: what the robots discovered")
    rows = []
    for p in range(1, N_POSTURES + 1):
        k = f"posture-{p}"
        m, t = summary["table_7_1"][k], THESIS_TABLE_7_1[k]
        rows.append([k, " ".join(map(str, m["events"])), " ".join(map(str, t["events"])),
                     " ".join(map(str, m["skills"])), " ".join(map(str, t["skills"])),
                     " ".join(f"{v:.2f}" for v in m["events_share"]),
                     " ".join(f"{v:.2f} [{lo:.2f}, {hi:.2f}]" for v, (lo, hi) in
                              zip(m["skills_share"], m.get("skills_share_ci95", [(0, 0)] * len(m["skills_share"]))))])
    rep.p(f"Events in order {', '.join(EVENTS)}; skills {', '.join(SKILL_LETTERS)}. 1 = happened / worked for at "
          "least one robot; the event share is the fraction of robots whose exploration produced the event from "
          "that posture; the skill share, per skill, the fraction of robots whose learnt skill works from that "
          "posture, with its 95 % Wilson interval. The rates of random movements (Table 7.1's events measured "
          "apart from learning) come from `python -m neuroimagery.robot.babble`.")
    rep.table(["posture", "events (run)", "events (thesis)", "skills (run)", "skills (thesis)", "event share",
               "skill share [95 %]"], rows)


def _differences(rep: Report, e, summary: dict) -> None:
    rep.h("What differs from the thesis, and why")
    rep.bullets(_pull_notes(e, summary) + [
        "The world is a pybullet rake-and-toy scene driven through the iCub's kinematics, not the iCub simulator; "
        "which movements touch or move the toy, and so which skills exist from which posture, follows from this "
        "physics (Table 7.1 above) rather than from the thesis's simulator.",
        "Several values are not given in the thesis (softmax and PI^BB temperatures, exploration noise, Hebbian and "
        "SOM rates, movement duration); they are named parameters of `conf/experiment/exp5.yaml` (docs/exp5.md).",
        "Each repetition acquires one skill library with all six detectors; a HP1 robot keeps the skills of its "
        "enabled detectors (its C1-C3 training replayed for those skills only), so groups of one repetition are "
        "paired rather than independent samples.",
        "The physics is deterministic, so the outcome of a given skill sequence from a posture is computed once; "
        "the thesis notes run-to-run variation of tool-toy contacts that this world does not have. "
        "A scene between moves keeps the toy where a move left it, turned as it left it.",
    ])


def _pull_notes(e, summary: dict) -> list[str]:
    """Where the learnt pull works from, and how the youngest and oldest tool-far successes happen."""
    c, t71 = summary["checks"], summary["table_7_1"]
    p_share = [t71[f"posture-{p}"]["skills_share"][0] for p in range(1, N_POSTURES + 1)]
    note = ("The thesis's HP1 pattern needs the pulling skill P to work only from postures 1-2 (Table 7.1). Here the "
            "learnt P works from postures 1-4 for " + ", ".join(f"{100 * v:.0f} %" for v in p_share) + " of the robots.")
    n_young, n_single = c.get("hp1_far_youngest_successes"), c.get("hp1_far_youngest_single_pull")
    if n_young:
        note += (f" Of the {n_young} tool-far successes of the youngest HP1 group (both strategies), {n_single} "
                 "were one pull from posture 4 and "
                 f"{n_young - n_single} other moves or sequences; the thesis expects almost none (\"sometimes, "
                 "performing pulling after touching can succeed\").")
    notes = [note]
    old = [r for r in summary.get("routes", []) if r["hypothesis"] == "hp1" and r["level"] == e.hp1_levels[-1]]
    if old and sum(r["successes"] for r in old):
        n = {k: sum(r[k] for r in old) for k in ("successes", "pull", "moves_then_pull", "other")}
        notes.append(
            f"In the thesis the tool-far success of older robots comes from moves that bring the tool behind the toy "
            f"followed by P (Fig. 7.8). Here, of the {n['successes']} tool-far success{'' if n['successes'] == 1 else 'es'} "
            f"at {e.hp1_ages[-1]} months "
            f"(both strategies), {n['moves_then_pull']} took that route, {n['pull']} were one pull and {n['other']} "
            "ended with a move that is not a pull: a touch or interaction primitive, learnt for another event, brought "
            "the toy into reach itself (table above).")
    return notes


def _cost(rep: Report, summary: dict) -> None:
    cost = summary.get("cost", {})
    rt = summary.get("runtime_s", {})
    rep.h("Cost")
    rep.p(f"{cost.get('tasks')} tasks, {summary.get('individuals')} individuals; rollouts {cost.get('rollouts')} "
          f"({cost.get('rollout_s')} s), renders {cost.get('renders')} ({cost.get('render_s')} s); summed task time "
          f"{cost.get('task_s_total')} s (CPU {cost.get('task_cpu_s_total', 'n/a')} s) of which skill acquisition "
          f"{cost.get('acquisition_s_total')} s. Wall clock of this call: "
          + (f"train {rt['train']} s" if rt.get("train") is not None else "no training (results read from checkpoint=DIR)")
          + (f" ({cost['tasks_read_back']} of the {cost.get('tasks')} tasks read back from an earlier call's "
             "checkpoints; their times are in the sums above)" if cost.get("tasks_read_back") else "")
          + (f"; {cost['libraries_reused']} tasks reused a stored skill library and ran action sequencing only"
             if cost.get("libraries_reused") else "")
          + f", evaluate {rt.get('evaluate')} s.")
