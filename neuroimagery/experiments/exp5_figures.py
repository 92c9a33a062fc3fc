"""Figures and report of Experiment 5 (Fig. 7.9, 7.10, the four situations, a retrieval film strip)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis import figures
from ..analysis.figures import plt, save
from ..analysis.report import Report, reproducibility_note
from ..analysis.robots import ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE
from ..models.tool_use import EVENTS, N_POSTURES, SKILL_LETTERS
from .exp5_config import THESIS, THESIS_TABLE_7_1
from .exp5_summary import group_rates

COLOURS = {"behind": "tab:blue", "far": "tab:red"}


def _pc_rgb(img) -> np.ndarray:
    """A PC map (2, H, W) (toy, tool) as an RGB picture: toy red, tool green on white."""
    a = np.asarray(img, dtype=float)
    if a.max() > 1.0:
        a = a / 255.0
    toy, tool = a[0], a[1]
    rgb = np.ones(toy.shape + (3,))
    rgb[..., 1] -= toy
    rgb[..., 2] -= toy
    rgb[..., 0] -= tool
    rgb[..., 2] -= tool
    return rgb.clip(0, 1)


def success_curves(summary: dict, hypothesis: str, path: Path, xkey: str, xlabel: str, title: str) -> Path:
    """Success rate (%) per group, one panel per strategy, a line per situation (as Fig. 7.9/7.10)."""
    g = pd.DataFrame([r for r in summary["groups"] if r["hypothesis"] == hypothesis])
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
    for ax, strat in zip(axes, ("reactive", "planning")):
        for sit, s in g[g["strategy"] == strat].groupby("situation", sort=False):
            s = s.sort_values("level")
            x = s["age_months"] if xkey == "age" else s["level"]
            ax.plot(x, 100 * s["success_rate"], marker="o", color=COLOURS.get(sit), label=f"{sit} (this run)")
            th = THESIS[hypothesis][sit]
            if th:
                lv = sorted(th)
                xs = [int(s.loc[s["level"] == k, "age_months"].iloc[0]) if xkey == "age" and (s["level"] == k).any() else k
                      for k in lv]
                ax.plot(xs, [100 * th[k] for k in lv], ls="--", marker="x", color=COLOURS.get(sit), alpha=0.6,
                        label=f"{sit} (thesis)")
        ax.set_title(f"({'ab'[strat == 'planning']}) {strat} system", fontsize=9)
        ax.set_xlabel(xlabel)
        ax.set_ylim(-5, 105)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (%)")
    axes[1].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def situations_figure(views: dict, path: Path) -> Path | None:
    """The eye's view of the four initial situations with their colour-filtered PC maps (``views``:
    :func:`neuroimagery.experiments.exp5.situation_views`); none without the eye's images."""
    if views["eye"] is None:
        return None
    fig, axes = plt.subplots(2, N_POSTURES, figsize=(11, 4.6))
    for p in range(1, N_POSTURES + 1):
        axes[0, p - 1].imshow(views["eye"][p - 1])
        axes[0, p - 1].set_title(f"posture-{p}" + (" (tool behind toy)" if p == 1 else " (tool far from toy)" if p == 4 else ""),
                                 fontsize=8)
        axes[1, p - 1].imshow(_pc_rgb(views["pc"][p - 1].numpy()))
        for ax in axes[:, p - 1]:
            ax.set_xticks([])
            ax.set_yticks([])
    axes[0, 0].set_ylabel("eye (V1)", fontsize=8)
    axes[1, 0].set_ylabel("PC (colour filtered)", fontsize=8)
    return save(fig, path)


def filmstrip(film: dict, path: Path) -> Path:
    """One planning retrieval: at each step the imagined (C3) outcome beside the real one."""
    frames = film["frames"]
    n = len(frames) + 1
    fig, axes = plt.subplots(2, n, figsize=(2.6 * n, 4.4), squeeze=False)
    axes[0, 0].imshow(_pc_rgb(film["start"].numpy()))
    axes[0, 0].set_title("start (real)", fontsize=8)
    axes[1, 0].axis("off")
    for i, f in enumerate(frames, start=1):
        axes[0, i].imshow(_pc_rgb(f["imagined"].numpy()))
        axes[0, i].set_title(f"step {i}: {f['action']} imagined", fontsize=8)
        axes[1, i].imshow(_pc_rgb(f["real"].numpy()))
        axes[1, i].set_title(f"step {i}: {f['action']} real", fontsize=8)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    title = (f"{film['strategy']} child, tool {film['situation']} ({film['hypothesis']} level {film['level']}): "
             "mental image (top) vs the scene after really moving (bottom)")
    fig.suptitle(textwrap.fill(title, max(24, int(2.6 * n * 11))), fontsize=9)  # 9 pt: about 11 characters an inch
    return save(fig, path)


@figures.timed
def draw_all(cfg, run, df: pd.DataFrame, summary: dict, results: list[dict], views: dict | None = None) -> None:
    """Every figure and TensorBoard image of a run; ``views`` are the initial situations as the robot
    sees them (:func:`neuroimagery.experiments.exp5.situation_views`), none off the robot world."""
    figs = {}
    figs["fig_7_9"] = success_curves(summary, "hp1", run.figures / "fig_7_9_hp1_skills.png", "age",
                                     "age (months) = 2..6 IM detectors", "HP1: success vs number of skills")
    figs["fig_7_10"] = success_curves(summary, "hp2", run.figures / "fig_7_10_hp2_trials.png", "level",
                                      "training trials", "HP2: success vs training trials")
    log_training_curves(run.logger, results, df)
    film = next((d["film"] for d in results if d.get("film")), None)
    if film is not None:
        figs["filmstrip"] = filmstrip(film, run.figures / "retrieval_filmstrip.png")
        log_film(run.logger, film)
    if views is not None:
        p = situations_figure(views, run.figures / "situations.png")
        if p is not None:
            figs["situations"] = p
        for k in range(1, N_POSTURES + 1):
            run.logger.image(f"situations/posture-{k}", _pc_rgb(views["pc"][k - 1].numpy()), 0)
    summary["figures"] = {k: str(Path(v).relative_to(run.root)) for k, v in figs.items()}


def training_curves(results: list[dict]) -> dict[str, list[float]]:
    """The skill-learning curves of every robot's library, averaged per event over the skills that
    reached each step: ``pibb/<event>/cost`` per PI^BB update (the update's mean event cost,
    1 - successes / samples, in the order the updates ran) and ``competence/<event>`` per epoch of
    Fig. 7.5's stopping rule."""
    sums: dict[str, list[list[float]]] = {}

    def add(tag: str, values) -> None:
        acc = sums.setdefault(tag, [])
        for i, v in enumerate(values):
            if i == len(acc):
                acc.append([])
            acc[i].append(float(v))

    for d in results:
        for sk in (d.get("library") or {}).get("skills", []):
            add(f"pibb/{sk['event']}/cost", [1.0 - op[2] for op in sk["log"] if op[0] == "c1"])
            add(f"competence/{sk['event']}", sk["competence"])
    return {tag: [sum(v) / len(v) for v in acc] for tag, acc in sums.items()}


def sequencing_curves(df: pd.DataFrame) -> dict[str, list[float]]:
    """C4's learning over the training trials of Fig. 7.6 (HP2 groups), per situation and strategy,
    averaged over the robots whose group had trial n: ``sequencing/<situation>/<strategy>/success``
    (the share of robots
    whose trial n succeeded, really or in imagination) and ``.../q_max`` (the largest action value of
    the robot's skills at the start after trial n)."""
    out: dict[str, list[float]] = {}
    if "train_q" not in df:
        return out
    d = df[(df["hypothesis"] == "hp2") & (df["training_trials"] > 0)]
    for (sit, strat), g in d.groupby(["situation", "strategy"], sort=False):
        for col, name in (("train_successes", "success"), ("train_q", "q_max")):
            seqs = [[float(v) for v in str(x).split(">")] for x in g[col] if isinstance(x, str) and x]
            n = max((len(q) for q in seqs), default=0)
            out[f"sequencing/{sit}/{strat}/{name}"] = [float(np.mean([q[i] for q in seqs if len(q) > i]))
                                                       for i in range(n)]
    return out


def log_training_curves(logger, results: list[dict], df: pd.DataFrame | None = None) -> None:
    """:func:`training_curves` (and :func:`sequencing_curves` of ``df``) as TensorBoard scalars
    ``train/...`` over their own steps (from 1)."""
    curves = training_curves(results) | (sequencing_curves(df) if df is not None else {})
    for tag, ys in curves.items():
        for i, y in enumerate(ys):
            logger.scalar(f"train/{tag}", y, i + 1)


def log_film(logger, film: dict) -> None:
    """TensorBoard: the filmed retrieval step by step (``film/real``, ``film/imagined``: the PC map
    after each attempt and the mental image C3 gave for it; step 0 = the start) and the filmed
    child's weights after its test (``brain/C1/...``, ``brain/C2/...``, ``brain/C3/...``,
    ``brain/C4/...``; :meth:`ToolUseBrain.maps`)."""
    logger.text("film/child", f"{film['hypothesis']} level {film['level']}, tool {film['situation']}, "
                              f"{film['strategy']} child: " + " > ".join(f["action"] for f in film["frames"]), 0)
    logger.image("film/real", _pc_rgb(film["start"].numpy()), 0)
    for i, f in enumerate(film["frames"], start=1):
        logger.image("film/real", _pc_rgb(f["real"].numpy()), i)
        logger.image("film/imagined", _pc_rgb(f["imagined"].numpy()), i)
    logger.maps(film.get("maps", {}), prefix="brain/")  # absent in checkpoints written before the maps


def group_table(e, h: str, cell) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the success table of hypothesis ``h`` (one row per group; per situation
    the reactive and planning cells from ``cell(h, level, situation, strategy)``, then the thesis)."""
    levels, ages, xl = ((e.hp1_levels, e.hp1_ages, "IM detectors") if h == "hp1"
                        else (e.hp2_trials, e.hp2_ages, "training trials"))
    rows = []
    for lv, age in zip(levels, ages):
        row = [str(lv), str(age)]
        for sit in e.situations:
            row += [cell(h, lv, sit, strat) for strat in ("reactive", "planning")]
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
    for h, xl in (("hp1", "IM detectors"), ("hp2", "training trials")):
        rep.h(f"{h.upper()}: success rate by {xl}")

        def cell(h, lv, sit, strat):
            r = rate.get((h, lv, sit, strat))
            return "-" if r is None else f"{100 * r:.0f} %"

        rep.table(*group_table(e, h, cell))
        key = "fig_7_9" if h == "hp1" else "fig_7_10"
        if key in summary.get("figures", {}):
            rep.figure(run.root / summary["figures"][key], f"Redrawn Fig. {'7.9' if h == 'hp1' else '7.10'}", run.root)
    c = summary["checks"]
    rep.h("Checks against the thesis")
    rho = c.get("hp1_far_spearman_pooled")
    far2 = np.mean([rate.get(("hp1", e.hp1_levels[0], "far", s)) or 0 for s in ("reactive", "planning")])
    far6 = np.mean([rate.get(("hp1", e.hp1_levels[-1], "far", s)) or 0 for s in ("reactive", "planning")])
    beh = [rate.get(("hp1", k, "behind", s)) for k in e.hp1_levels for s in ("reactive", "planning")]
    beh = [b for b in beh if b is not None]
    rep.bullets([
        f"HP1 tool behind toy: {100 * min(beh):.0f}-{100 * max(beh):.0f} % over ages and strategies (thesis ~90 %, 100 % at 14 months)." if beh else "HP1 behind: not run",
        f"HP1 tool far from toy: {100 * far2:.0f} % at {e.hp1_ages[0]} months, {100 * far6:.0f} % at {e.hp1_ages[-1]} months "
        f"(thesis ~0 % and ~60 %).",
        f"Spearman's rho of far-from-toy success over the HP1 groups: pooled {fmt(rho)}, reactive "
        f"{fmt(c.get('hp1_far_spearman_reactive'))}, planning {fmt(c.get('hp1_far_spearman_planning'))} (target >= 0.8).",
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
              f"with `python -m neuroimagery.pool`).")
        rep.table(["claim", "this run", "holds"], [[c["claim"], c["value"], "yes" if c["holds"] else "**no**"] for c in claims])
    if summary.get("effects"):
        rep.h("Effects, the robot as the unit")
        rep.effects(summary["effects"], ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE)
    routes = [r for r in summary.get("routes", []) if r["hypothesis"] == "hp1"]
    if routes:
        rep.h("How the tool-far successes happen (HP1)")
        rep.p("Each successful tool-far test sorted by its moves: one pull alone; other moves and then a pull (the "
              "thesis's route, Fig. 7.8: a move that brings the tool behind the toy, then P); or a last move that is "
              "not a pull (touch or an interaction primitive that itself brought the toy into reach). "
              "summary.json `routes` holds the same counts for every tool-far group.")
        by = {(r["level"], r["strategy"]): r for r in routes}
        has_avail = all("available" in r for r in routes)
        has_imag = all("imagined" in r for r in routes)
        has_still = any(r.get("no_move") for r in routes)
        if has_avail:
            rep.p("The next column counts the robots for which the world holds a retrieval of one or two moves "
                  "with their primitives (individuals.csv `routes_1`, `routes_2`), whether or not they find it: "
                  "what the world offers, against what the learners make of it.")
        if has_imag:
            rep.p("The last column counts the robots whose mental images (C3 run backwards from the far "
                  "situation) show the toy in reach after one or two moves (`imagined_1`, `imagined_2`), and in "
                  "brackets those with such an imagined route that also works in the world (`imagined_true`): "
                  "what a planning child can learn in mind.")
        if has_still:
            rep.p(f"With `sequencing.active_threshold: {e.sequencing.active_threshold}` a child moves only a primitive whose PMC activity "
                  "(C1 + C4) exceeds it (Fig. 7.6 draws among the *active* PMC units); the column \"did not move\" counts "
                  "the tests, reactive / planning, in which nothing was active in the far situation.")
        rows = []
        for k, age in zip(e.hp1_levels, e.hp1_ages):
            row = [k, age]
            for strat in ("reactive", "planning"):
                r = by.get((k, strat))
                row.append("-" if r is None else f"{r['successes']} of {r['n']}: {r['pull']} / {r['moves_then_pull']} / {r['other']}")
            r = by.get((k, "reactive")) or by.get((k, "planning"))
            if has_avail:
                row.append("-" if r is None else f"{r['available']} of {r['n']}")
            if has_imag:
                row.append("-" if r is None else f"{r['imagined']} ({r['imagined_true']}) of {r['n']}")
            if has_still:
                row.append(" / ".join(str(by[(k, st)].get("no_move", 0)) if (k, st) in by else "-"
                                      for st in ("reactive", "planning")))
            rows.append(row)
        rep.table(["IM detectors", "age (months)", "reactive: successes: pull / moves then pull / other",
                   "planning: successes: pull / moves then pull / other"]
                  + (["robots with a 1-2 move retrieval"] if has_avail else [])
                  + (["robots with an imagined 1-2 move retrieval (true)"] if has_imag else [])
                  + (["did not move, reactive / planning"] if has_still else []), rows)
    mech = summary.get("mechanism") or {}
    if mech:
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
    for key, cap in (("situations", "The eye's view of the four initial situations and their PC maps"),
                     ("filmstrip", "One retrieval by a planning child: imagined outcome (C3) above the real scene")):
        if key in summary.get("figures", {}):
            rep.figure(run.root / summary["figures"][key], cap, run.root)
    rep.h("What differs from the thesis, and why")
    t71 = summary["table_7_1"]
    p_share = [t71[f"posture-{p}"]["skills_share"][0] for p in range(1, N_POSTURES + 1)]
    p_note = ("The thesis's HP1 pattern needs the pulling skill P to work only from postures 1-2 (Table 7.1). Here the "
              "learnt P works from postures 1-4 for " + ", ".join(f"{100 * v:.0f} %" for v in p_share) + " of the robots")
    n_young, n_single = c.get("hp1_far_youngest_successes"), c.get("hp1_far_youngest_single_pull")
    p_note += "."
    if n_young:
        p_note += (f" Of the {n_young} tool-far successes of the youngest HP1 group (both strategies), {n_single} "
                   "were one pull from posture 4 and "
                   f"{n_young - n_single} other moves or sequences; the thesis expects almost none (\"sometimes, "
                   "performing pulling after touching can succeed\").")
    old = [r for r in summary.get("routes", []) if r["hypothesis"] == "hp1" and r["level"] == e.hp1_levels[-1]]
    bullets = [p_note]
    if old and sum(r["successes"] for r in old):
        n = {k: sum(r[k] for r in old) for k in ("successes", "pull", "moves_then_pull", "other")}
        bullets.append(
            f"In the thesis the tool-far success of older robots comes from moves that bring the tool behind the toy "
            f"followed by P (Fig. 7.8). Here, of the {n['successes']} tool-far success{'' if n['successes'] == 1 else 'es'} "
            f"at {e.hp1_ages[-1]} months "
            f"(both strategies), {n['moves_then_pull']} took that route, {n['pull']} were one pull and {n['other']} "
            "ended with a move that is not a pull: a touch or interaction primitive, learnt for another event, brought "
            "the toy into reach itself (table above).")
    rep.bullets(bullets + [
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
        + ("A scene between moves keeps the toy where a move left it, turned as it left it (`world.toy_turn: keep`)."
           if e.world.toy_turn == "keep" else
           "A scene between moves keeps where the toy is but not how a move turned it (`world.toy_turn: reset`): the "
           "next move starts from the toy set square at that place (docs/exp5.md)."),
    ])
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
    rep.p(reproducibility_note(cfg.seed))
    rep.write(run.report_path)


def fmt(v, pct: bool = False) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "n/a"
    return f"{100 * v:.0f} %" if pct else f"{v:.2f}"
