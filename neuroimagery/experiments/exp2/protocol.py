"""Experiment 2 (thesis 5.2): mental rotation through motor models, with wrist proprioception.

Training follows Table 5.1 and the motor babbling procedure (a)-(g), with two departures: C2 learns
on the 1,960 babbling steps of C9 and C10 (Table 5.1: 84 cycles), and C9, C10, C2 learn after the
SOM M1_1 has finished rather than step by step beside it (docs/exp2.md). The test shows all 196 pairs
(14 images x 14 images: objects A/B at -90..90 deg in 30-deg steps) to each of ``participants``
simulated robots, once per proprioception condition (``none``, ``match``, ``mismatch``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from ...core import progress
from ...analysis import figures
from ...analysis.report import Report, fmt_p
from ...analysis.summary import compare_rates, compare_rt, effect, equivalent_levels, holm, paired_by_participant, slope_by_participant, summarise_trials
from ...core.thesis import EXP2 as THESIS
from ...models.rotation_motor import ANGLES, MotorRotationModel
from .config import Exp2Config
from ..chapter5.protocol import auto_threads, count_trials, edge_maps, finish_report, load_model, objects_of, record_figures_and_scalars, stimulus_set, to_np, train_and_save, trials_frame

CONDITIONS = ("none", "match", "mismatch")
TARGETS = {"all/none": {"rotation_success_rate": THESIS["rotation success"].value,
                        "correct_rate": THESIS["correct answers"].value}}


def _e(cfg) -> Exp2Config:
    e = cfg.experiment
    if cfg.preset != "quick":
        return e
    return replace(e, som=replace(e.som, iterations=min(e.som.iterations, e.quick.som_iterations)))


@auto_threads
def train(cfg, run):
    return train_and_save(cfg, run, MotorRotationModel, _e(cfg), ANGLES)


@auto_threads  # the weights are formed again on load, on the threads they were trained on
def load(cfg, checkpoint_dir):
    return load_model(cfg, checkpoint_dir, MotorRotationModel, _e(cfg))


def run_test(cfg, model, sset, test, condition, record=0):
    objs = objects_of(sset)
    items = [(o, a) for o in objs for a in ANGLES]
    pairs = [(r, t) for r in items for t in items]
    maps = edge_maps(cfg, sset, items).reshape(len(items), -1)
    idx = {it: i for i, it in enumerate(items)}
    P = model.participants
    rot = maps[[idx[r] for r, _ in pairs]].expand(P, -1, -1)
    tgt = maps[[idx[t] for _, t in pairs]].expand(P, -1, -1)
    out = model.trial(rot, tgt, condition, record=record)  # the images only
    # the rotation is scored against the target's true orientation here, outside the model
    tgt_angle = torch.tensor([t[1] for _, t in pairs], dtype=out["final_angle"].dtype).expand(P, -1)
    out["rotated_ok"] = out["stopped"] & ((out["final_angle"] - tgt_angle).abs() < 15.0)
    app = sset.appearances[0]
    rows = []
    for p in range(P):
        for i, (r, t) in enumerate(pairs):
            same = r[0] == t[0]
            yes = bool(out["yes"][p, i])
            rows.append(dict(participant=p, test=test, condition=condition, target_object=t[0], target_angle=t[1],
                             target_appearance=app, rotated_object=r[0], rotated_angle=r[1], rotated_appearance=app,
                             disparity=abs(r[1] - t[1]), same=same, answer="yes" if yes else "no", correct=yes == same,
                             rotation_steps=int(out["steps"][p, i]), rotated_ok=bool(out["rotated_ok"][p, i]),
                             rt=int(out["rt"][p, i]), signed_disparity=r[1] - t[1], pair_type=r[0] + t[0]))
    return count_trials(rows, test, condition), out


@auto_threads
def evaluate(cfg, run, trained) -> dict:
    model = trained
    model.eval()
    df, frames = _all_trials(cfg, model)
    run.write_csv("trials.csv", df)
    tests = summarise_trials(df)
    base = df[(df["test"] == "all") & (df["condition"] == "none")]
    tests["all/none"]["rt_by_pair_type"] = {k: round(float(g["rt"].mean()), 3) for k, g in base.groupby("pair_type")}
    tests["all/none"]["rotation_failures"] = base[~base["rotated_ok"]].groupby("participant").size().to_dict()
    summary = _summary(df, base, tests)
    shown = _sample_trials(run, base, frames)
    shown["fig5_8a_rt"] = figures.rt_by_disparity(base, run.figures / "fig5_8a_rt.png", groups=("pair_type",),
                                                  ylabel="RT (cycles = ms)", title="RT by object pair (AA, AB, BA, BB)")
    shown["fig5_8b_rt"] = figures.rt_by_disparity(df[df["test"] == "all"], run.figures / "fig5_8b_rt.png",
                                                  groups=("condition",), ylabel="RT (cycles = ms)",
                                                  title="RT by proprioception condition")
    return record_figures_and_scalars(run, summary, shown, tests, "exp2")


def _all_trials(cfg, model):
    """Every test's trials (set L in each proprioception condition, then a stimulus folder's own
    set), and the recorded frames of the first trials without proprioception."""
    from ...vision.stimulus_sets import get_stimulus_set

    rows, frames = [], None
    custom = stimulus_set(cfg) if cfg.stimuli.kind == "folder" else None
    pairs = lambda sset: (len(objects_of(sset)) * len(ANGLES)) ** 2  # noqa: E731  (every item against every item)
    progress.expect(model.participants * (len(CONDITIONS) * pairs(get_stimulus_set("L")) + (pairs(custom) if custom else 0)))
    for cond in CONDITIONS:
        r, out = run_test(cfg, model, get_stimulus_set("L"), "all", cond, record=196 if cond == "none" else 0)
        rows += r
        if cond == "none":
            frames = out["frames"]
    if custom is not None:
        r, _ = run_test(cfg, model, custom, "custom", "none")
        rows += r
    return trials_frame(rows), frames


def _paired(a, b) -> dict:
    """Paired t-test over the same (participant, pair) trials in two conditions."""
    from scipy import stats

    t = stats.ttest_rel(a["rt"].values, b["rt"].values)
    return {"mean_a": round(float(a["rt"].mean()), 3), "mean_b": round(float(b["rt"].mean()), 3),
            "diff": round(float(a["rt"].mean() - b["rt"].mean()), 3), "t": round(float(t.statistic), 4),
            "p": float(t.pvalue), "n_pairs": int(len(a))}


def _summary(df, base, tests: dict) -> dict:
    from scipy import stats

    mis = df[(df["test"] == "all") & (df["condition"] == "mismatch")]
    mat = df[(df["test"] == "all") & (df["condition"] == "match")]
    f = stats.f_oneway(*[g["rt"].values for _, g in base.groupby("pair_type")])
    # the participants evaluated: with checkpoint=DIR those of the loaded model, not cfg.participants
    return {"experiment": "exp2", "participants": int(df["participant"].nunique()), "tests": tests,
            "proprioception": {"rt_mismatch_vs_none_paired": _paired(mis, base),
                               "rt_match_vs_none_paired": _paired(mat, base),
                               "rt_mismatch_vs_none": compare_rt(mis["rt"], base["rt"]),
                               "rt_match_vs_none": compare_rt(mat["rt"], base["rt"]),
                               "correct_mismatch_vs_none": compare_rates(mis["correct"], base["correct"])},
            "object_type_anova": {"F": round(float(f.statistic), 4) if np.isfinite(f.statistic) else None,
                                  "p": float(f.pvalue) if np.isfinite(f.pvalue) else None},
            "targets": TARGETS, "effects": effects(df)}


# the maps of a sample trial's figure (Fig. 5.7) and the shape of a map a frame lacks
SAMPLE_MAPS = {"PP": (32, 32), "SS": (31, 100), "M1_1": (64, 64), "PFC_1": (32, 32), "PFC_2": (64, 64), "PMC_2": (10, 20)}


def _sample_trials(run, base, frames) -> dict:
    """Fig. 5.7a/b: participant 0's first trial rotated in three steps or more, and its first failed rotation."""
    shown = {}
    b0 = base[base["participant"] == 0].reset_index(drop=True)
    succ = b0.index[b0["rotated_ok"] & (b0["rotation_steps"] >= 3)]
    fail = b0.index[~b0["rotated_ok"]]
    for tag, idx in (("fig5_7a_success", succ), ("fig5_7b_failure", fail)):
        if not len(idx):
            continue
        k = int(idx[0])
        row, fr = b0.loc[k], frames[k]
        panels = [{kk: to_np(f_[kk]) if kk in f_ else np.zeros(shp) for kk, shp in SAMPLE_MAPS.items()} for f_ in fr]
        title = (f"{row['rotated_object']} {row['rotated_angle']:.0f} -> {row['target_object']} "
                 f"{row['target_angle']:.0f}: {row['rotation_steps']} steps, answer {row['answer']}")
        shown[tag] = figures.map_panels(panels, run.figures / f"{tag}.png", title,
                                        [f"step {i + 1}" for i in range(len(fr) - 1)] + ["match/answer"])
        for i, f_ in enumerate(fr):
            run.logger.maps(f_, step=i, prefix=f"exp2/{tag}/")
    return shown


def effects(df) -> list[dict]:
    """The effects the thesis states (section 5.2.2, Figs. 5.8a and 5.8b) on the trials of
    test ``all``, each with the participant as the unit; Holm's correction over the family."""
    a = df[df["test"] == "all"]
    base, mis = a[a["condition"] == "none"], a[a["condition"] == "mismatch"]
    rt_bound = step_rt(base)
    rows = [effect("RT rises with disparity (none)", ">0", slope_by_participant(base), "mean_slope"),
            effect("RT: mismatch slower than none", ">0", paired_by_participant(mis, base, "rt")),
            effect("correct rate: mismatch = none", "~0",
                   paired_by_participant(mis.assign(c=mis["correct"].astype(float)),
                                         base.assign(c=base["correct"].astype(float)), "c"), bound=RATE_BOUND)]
    rows.append(effect("RT: no effect of the object types (AA, AB, BA, BB; largest pairwise difference)", "~0",
                       equivalent_levels(base, "pair_type", "rt", rt_bound) if rt_bound else {}, bound=rt_bound))
    return holm(rows)


RATE_BOUND = 0.05  # equivalence bound of a difference of rates: 5 points (docs/choices.md)


def step_rt(base) -> float | None:
    """The RT of one rotation step, the equivalence bound of an RT difference (docs/choices.md):
    the participants' mean least-squares slope of RT on the rotation steps a trial made, in
    condition ``none`` (``base``); None when no participant's steps vary."""
    res = slope_by_participant(base, x="rotation_steps", y="rt")
    m = res["mean_slope"]
    return round(float(m), 3) if m is not None and m > 0 else None


def _pv(p) -> str:
    """``= 0.012`` or ``< 1e-16``: a p value after its symbol."""
    t = fmt_p(p)
    return t if t.startswith("<") else f"= {t}"


def report(cfg, run, summary) -> None:
    T = summary["tests"]
    n = T["all/none"]
    pr = summary["proprioception"]
    r = Report("Experiment 2: mental rotation through motor models and proprioception (thesis 5.2)")
    r.chance_warning(summary)
    r.p(f"Preset `{cfg.preset}`. {summary['participants']} simulated robots, 196 pairs each, three proprioception conditions. "
        f"SOM training steps: {_e(cfg).som.iterations} (thesis 10,000).")
    r.h("Results beside the thesis")
    success, correct = THESIS["rotation success"].value, THESIS["correct answers"].value
    r.targets([("rotation success (none)", n["rotation_success_rate"], success, True),
               ("correct answers (none)", n["correct_rate"], correct, True),
               ("r(disparity, mean RT) (none)", n["rt_r"], None, False),
               ("correct answers (mismatch)", T["all/mismatch"]["correct_rate"], correct, True)])
    r.h("Effects, the participant as the unit")
    r.effects(summary.get("effects", []))
    r.h("Trial-level tests (trials as independent samples)")
    m, w = pr["rt_mismatch_vs_none_paired"], pr["rt_mismatch_vs_none"]
    mp = pr["rt_match_vs_none_paired"]
    r.p(f"Mismatched proprioception: mean RT {m['mean_a']} vs {m['mean_b']} with none "
        f"(paired t over the {m['n_pairs']} same trials: t = {m['t']}, p {_pv(m['p'])}; Welch t = {w['t']}, "
        f"p {_pv(w['p'])}). Matched: mean RT {mp['mean_a']} (paired t = {mp['t']}, p {_pv(mp['p'])}). Correct answers {pr['correct_mismatch_vs_none']['rate_a']} vs "
        f"{pr['correct_mismatch_vs_none']['rate_b']} (p {_pv(pr['correct_mismatch_vs_none']['p'])}).")
    a = summary["object_type_anova"]
    r.p(f"Object type (AA, AB, BA, BB) mean RT: {n['rt_by_pair_type']}; one-way ANOVA F = {a['F']}, p {_pv(a['p'])}.")
    r.h("Why the numbers differ")
    r.bullets([
        "The thesis's errors come from overlapping M1_1 clusters and PFC_2; here they depend on this project's "
        "drawn L, cluster widths, SOM schedule and the field's constants (none given in the thesis).",
        "The current wrist posture at the start of a trial is read from the image through C2 run backwards "
        "(the thesis does not say how SS is first set).",
        "The SS competition runs along the wrist-angle axis (100 units); the object row is read at the winner.",
        "Proprioception pre-activates SS (the field starts at rest + the felt cluster, which stays on at "
        f"{_e(cfg).proprio_gain} of the forward model's strength). In the match condition the felt posture is the "
        "actual wrist, which executes every M1_2 command; in the mismatch condition it is a random posture cluster.",
        "Rotation success is scored against the target's true orientation.",
    ])
    finish_report(r, cfg, run, summary, ("The model only knows "
            "the two trained objects: C2 can only imagine those, so a user's shape is replaced by the trained L "
            "during rotation. These numbers show that limit."))
