"""Experiment 4 (thesis section 6.2): generalisation, decision making and embodiment in mental
rotation. Model: :class:`neuroimagery.models.rotation_embodied.RotationEmbodied`.

Protocol: forward models C1-C3 learn from three-dot images rotated by +step / 0 / -step; the
posture maps C16 and C17 learn the wrist posture of every set-A image (supervised Kohonen). Tests
Recog (set A), Gen1 (set B) and Gen2 (set C), 432 pairs each, with proprioception none, match
(congruent) and mismatch (incongruent); the noise variant (U[-0.5, 0.5] on PPCp each step) is run
in each condition on the tests listed in ``noise_tests``. RT = accumulator cycles (10 per step).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from ...core import progress
from ...analysis import figures
from ...models.rotation_embodied_params import PROPRIOCEPTION as CONDITIONS
from ...analysis.report import Report, fmt_p, reproducibility_note
from ...analysis.summary import (compare_rates, compare_rt, effect, holm, paired_by_participant, paired_means,
                                 slope_by_participant, summarise_trials)
from ...nn import seeding
from ..chapter6 import protocol as pc
from .config import TESTS
from ...core.thesis import EXP4 as THESIS_TARGETS

UNITS = {"PMCm": ["l", "s", "r"], "PMCd": ["YES", "NO"]}  # what each unit of the 1-D maps stands for
RT_BOUND = 10.0  # equivalence bound of an RT difference: one rotation step, 10 accumulator cycles (docs/choices.md)
THESIS = {k.removesuffix(" correct rate"): t.value for k, t in THESIS_TARGETS.items() if k.endswith("correct rate")}


def _ids(cfg) -> list[int]:
    return list(range(cfg.participants))


def _model(cfg, ids):
    from ...models.rotation_embodied import RotationEmbodied

    return RotationEmbodied(cfg.experiment, seeding.participant_generators(cfg.seed, ids, stream=0), ids)


def train_model(cfg, ids, eye=None):
    """Train the participants ``ids`` (a batched run of them equals their solo runs)."""
    e = cfg.experiment
    eye = pc.make_eye(cfg) if eye is None else eye
    model = _model(cfg, ids)
    gens = seeding.participant_generators(cfg.seed, ids, stream=1)
    n_img = e.quick.fm_images if cfg.preset == "quick" else e.fm.images
    X, Y, moves = pc.three_dot_training_rows(gens, n_img, model.step_angles, e.map_size, e.fm.dot_inner)
    model.fit_forward_models(X, Y, moves, e.fm.batch, progress=pc.batches_bar("forward model"))
    bank = pc.training_bank(cfg, eye)
    pc.train_posture_maps(cfg, eye, model, e.ppc.angles, gens, bank=bank)
    model.calibrate(bank.maps, *bank.structure())  # PMCd's gain and leak (rules R1, R2 of docs/choices.md)
    return model.eval()


def train(cfg, run):
    from ...models.sequence_checkpoint import compact_state

    model = train_model(cfg, _ids(cfg))
    # compact: the forward models' training sequence instead of their weights (docs/results.md)
    run.save_checkpoint("exp4", compact_state(model))
    return model


def load(cfg, checkpoint_dir):
    """The trained model of ``checkpoints/exp4.pt``: compact (the forward models trained again on
    the stored sequence) or full (``state_dict``, as earlier versions wrote)."""
    from pathlib import Path

    from ...core.errors import UserInputError
    from ...models import sequence_checkpoint as sc
    from ...core.checkpoints import load_checkpoint

    ck = load_checkpoint(checkpoint_dir, "exp4")
    where = Path(checkpoint_dir) / "checkpoints" / "exp4.pt"
    if "state_dict" in ck:
        model = _model(cfg, ck["participants"])
        try:
            model.load_state_dict(ck["state_dict"])
        except RuntimeError as err:  # e.g. a checkpoint of a version without PMCd's 'leak'
            raise UserInputError(f"checkpoint {where} does not fit this version's model (train again): {err}") from err
        return model.eval()
    model = _model(cfg, ck.get("participants", []))
    try:
        sc.load_compact_state(model, ck)
    except (ValueError, KeyError) as err:
        raise UserInputError(f"checkpoint {where}: {err}") from err
    return model


def _test_sets(cfg):
    e = cfg.experiment
    if cfg.stimuli.kind == "folder":
        return {"custom": pc.stimulus_set(cfg, e.recog_set)}
    return {t: pc.stimulus_set(cfg, getattr(e, f"{t}_set"), use_user_folder=False) for t in TESTS}


def _subset(bank, table, cfg):
    if cfg.preset != "quick":
        return table
    keep = bank.set.objects[: cfg.experiment.quick.objects]
    return table[table["target_object"].isin(keep)].reset_index(drop=True)


def run_tests(cfg, model, eye=None, record: int = 0):
    """All tests and conditions -> (trials DataFrame, sample histories, banks)."""
    e = cfg.experiment
    eye = pc.make_eye(cfg) if eye is None else eye
    ids, P = model.participant_ids, model.participants
    frames, histories, banks, tables = [], {}, {}, {}
    for test, sset in _test_sets(cfg).items():  # every test's trials first: the test bar's total
        banks[test] = bank = pc.test_bank(cfg, eye, sset, len(banks))
        noisy = [False] + ([True] if (test in e.noise_tests or test == "custom") else [])
        tables[test] = _subset(bank, pc.trial_table(bank, test, "none"), cfg), noisy
    progress.expect(sum(len(t) * len(noisy) * len(CONDITIONS) * P for t, noisy in tables.values()))
    k = 0
    for test, (table, noisy) in tables.items():
        bank = banks[test]
        tgt, rot = pc.trial_looks(cfg, bank, table, ids, list(banks).index(test))
        names, conds = [], []
        for noise in noisy:
            for cond in CONDITIONS:
                names.append(f"noise-{cond}" if noise else cond)
                conds.append((cond, noise, seeding.participant_generators(cfg.seed, ids, stream=100 + k)))
                k += 1
        # all conditions of a test in one batch: they share the targets and the first step
        shown = pc.candidate_rows(table, record)  # the sample trials are chosen among these after the run
        for name, out in zip(names, model.run_conditions(tgt, rot, conds, record=shown)):
            histories[f"{test}/{name}"] = pc.sample_history(table, out, shown, record)
            frames.append(pc.trial_rows(table.assign(condition=name), out, ids))
    return pd.concat(frames, ignore_index=True), histories, banks


def _stats(df: pd.DataFrame) -> dict:
    """Embodiment comparisons (Welch t on RT, chi-square on correct answers)."""
    out = {}
    for test in df["test"].unique():
        d = df[df["test"] == test]
        g = {c: d[d["condition"] == c] for c in d["condition"].unique()}
        for a, b in (("mismatch", "none"), ("match", "none"), ("noise-match", "noise-none"),
                     ("noise-mismatch", "noise-none"), ("noise-none", "none")):
            if a in g and b in g:
                out[f"{test}:{a}-vs-{b}"] = {"rt": compare_rt(g[a]["rt"], g[b]["rt"]),
                                             "correct": compare_rates(g[a]["correct"], g[b]["correct"])}
                big = d["disparity"].max() / 2
                ga, gb = g[a][g[a]["disparity"] >= big], g[b][g[b]["disparity"] >= big]
                out[f"{test}:{a}-vs-{b}:disparity>={int(big)}"] = {"rt": compare_rt(ga["rt"], gb["rt"]),
                                                                    "correct": compare_rates(ga["correct"], gb["correct"])}
    return out


def effects(df: pd.DataFrame) -> list[dict]:
    """The effects the thesis states (section 6.2.3), each judged with the participant as the unit:
    paired t-tests over participants on their mean RT or correct rate, one-sample t-tests of their
    RT-disparity slopes; Holm's correction over the family."""
    rows = []
    cells = dict(tuple(df.groupby(["test", "condition"], sort=False)))  # each (test, condition)'s rows, in order
    cond = lambda t, c: cells.get((t, c), df.iloc[:0])  # noqa: E731
    conds = {t: {c for tt, c in cells if tt == t} for t, _ in cells}
    tests = [t for t in TESTS + ("custom",) if t in conds]  # custom: a user's folder
    for t in tests:
        rows.append(effect(f"{t}: RT rises with disparity", ">0", slope_by_participant(cond(t, "none")), "mean_slope"))
    for t in tests:
        if {"none", "mismatch"} <= conds[t]:
            a, b = cond(t, "mismatch"), cond(t, "none")
            rows.append(effect(f"{t}: incongruent movement lengthens RT", ">0", paired_by_participant(a, b, "rt")))
            rows.append(effect(f"{t}: incongruent movement lowers the correct rate", "<0",
                               paired_by_participant(a.assign(correct=a["correct"].astype(float)),
                                                     b.assign(correct=b["correct"].astype(float)), "correct")))
            m = cond(t, "match")
            rows.append(effect(f"{t}: congruent movement, no gain in RT (ceiling)", "~0", paired_by_participant(m, b, "rt"),
                               bound=RT_BOUND))
        if {"noise-none", "noise-match"} <= conds[t]:
            far = lambda d: d[d["disparity"] >= 120]  # noqa: E731
            a, b = far(cond(t, "noise-match")), far(cond(t, "noise-none"))
            rows.append(effect(f"{t}, noise, 120-150 deg: congruent movement shortens RT", "<0",
                               paired_by_participant(a, b, "rt")))
            rows.append(effect(f"{t}, noise, 120-150 deg: congruent movement raises the correct rate", ">0",
                               paired_by_participant(a.assign(correct=a["correct"].astype(float)),
                                                     b.assign(correct=b["correct"].astype(float)), "correct")))
    return holm(rows)


def _stats_by_disparity(df: pd.DataFrame) -> dict:
    """The proprioception comparisons of each test at each disparity, the participant as the unit:
    paired t-tests of the participants' mean RT and correct rate (``paired_by_participant``), with
    Holm's correction over every p of the table (``{"<test>:<a>-vs-<b>": {"<disparity>": {...}}}``;
    ``rt_a``/``rt_b`` and ``correct_a``/``correct_b`` the means over the participants)."""
    out, ps = {}, []
    # every participant's mean RT and correct rate in every (test, condition, disparity), at once
    means = df.assign(correct=df["correct"].astype(float)).groupby(
        ["test", "condition", "disparity", "participant"], sort=True)[["rt", "correct"]].mean()
    cells = {key: g.droplevel([0, 1, 2]) for key, g in means.groupby(level=[0, 1, 2], sort=False)}
    empty = means.iloc[:0].droplevel([0, 1, 2])
    for test in df["test"].unique():
        d = df[df["test"] == test]
        conds = set(d["condition"].unique())
        for a, b in (("match", "none"), ("mismatch", "none"), ("noise-match", "noise-none"), ("noise-mismatch", "noise-none")):
            if a not in conds or b not in conds:
                continue
            rows = {}
            for disp in np.sort(d["disparity"].unique()):
                ga, gb = cells.get((test, a, disp), empty), cells.get((test, b, disp), empty)
                rt, cr = paired_means(ga["rt"], gb["rt"]), paired_means(ga["correct"], gb["correct"])
                row = {"rt_a": rt["mean_a"], "rt_b": rt["mean_b"], "rt_p": rt["p"],
                       "correct_a": cr["mean_a"], "correct_b": cr["mean_b"], "correct_p": cr["p"], "n": rt["n"]}
                rows[str(int(disp))] = row
                ps += [(row, "rt"), (row, "correct")]
            out[f"{test}:{a}-vs-{b}"] = rows
    tested = [(row, k) for row, k in ps if row[f"{k}_p"] is not None]
    adjusted = holm([{"p": row[f"{k}_p"], "expected": ">0", "value": None, "holds": None} for row, k in tested])
    for (row, k), h in zip(tested, adjusted):
        row[f"{k}_p_holm"] = h["p_holm"]
    for row, k in ps:
        row.setdefault(f"{k}_p_holm", None)
    return out


def _rt_vs_steps(df: pd.DataFrame) -> dict:
    """Mean RT of the decided trials of condition none, grouped by the rotation steps each trial
    itself made. RT counts 10 accumulator cycles per step and the decision falls within the last
    step's 10 cycles, so every group lies in (10 n, 10 n + 10] by construction: a check of the
    bookkeeping, not of the model's performance."""
    d = df[(df["condition"] == "none") & df["decided"]]
    g = d.groupby("rotation_steps")["rt"].mean()
    return {str(int(n)): round(float(v), 2) for n, v in g.items()}


def _rt_vs_required_steps(df: pd.DataFrame, step_deg: float) -> dict:
    """The thesis's measure (Fig. 6.9a, 6.2.2): mean RT of the decided trials of condition none,
    grouped by the number n of ``step_deg`` rotation steps the pair's disparity requires
    (disparity / step_deg, rounded). A model that always rotates straight to the target and decides
    at once has RT just above 10 n; detours, stops at a wrong angle and slow decisions raise it.
    Returns ``{"all": {n: RT}, "<test>": {n: RT}, ...}``."""
    d = df[(df["condition"] == "none") & df["decided"]]
    n = (d["disparity"].astype(float) / float(step_deg)).round().astype(int)
    per = lambda x, k: {str(int(a)): round(float(v), 2) for a, v in x["rt"].groupby(k).mean().items()}  # noqa: E731
    out = {"all": per(d, n)}
    for test, g in d.groupby("test", sort=False):
        out[str(test)] = per(g, n[g.index])
    return out


def evaluate(cfg, run, trained) -> dict:
    e = cfg.experiment
    eye = pc.make_eye(cfg)
    df, histories, banks = run_tests(cfg, trained, eye, record=cfg.logger.sample_trials)
    run.write_csv("trials.csv", df)
    tests = summarise_trials(df)
    time_outs = pc.add_time_outs(tests, df)
    # the participants evaluated: with checkpoint=DIR those of the loaded model, not cfg.participants
    summary = {"experiment": "exp4", "participants": int(df["participant"].nunique()), "tests": tests, "time_out_rates": time_outs,
               "targets": {k: {"correct_rate": v} for k, v in THESIS.items()},
               "effects": effects(df), "statistics": _stats(df), "statistics_by_disparity": _stats_by_disparity(df),
               "rt_by_rotation_steps": _rt_vs_steps(df),
               "rt_by_required_steps": _rt_vs_required_steps(df, e.step_deg)}
    # generalisation of the three-dot forward models to the test shapes
    iou = {}
    for test, bank in banks.items():
        iou[test] = pc.generalisation_iou(lambda x: trained.forward_step(
            x.expand(trained.participants, -1, -1) if x.shape[0] == 1 else x,
            torch.zeros(trained.participants, x.shape[1], dtype=torch.long)), bank, e.step_deg, 3, e.map_size)
    summary["forward_model_iou"] = iou
    for key, hist in histories.items():
        pc.log_history(run.logger, hist["trials"], key, hist["names"])
    _figures(run, df, histories, e.step_deg)
    return summary


@figures.timed
def _figures(run, df, histories, step_deg: float) -> None:
    f = run.figures
    base = df[df["condition"] == "none"]
    thesis = {k.split("/")[0]: v for k, v in THESIS.items()}
    if set(base["test"]) - {"custom"}:  # a user's folder alone: its own figures below say the same
        figures.rt_by_disparity(base, f / "fig6_9a_rt.png", groups=("test",), title="Fig. 6.9a RT (cycles)",
                                ylabel="RT (accumulator cycles)")
        figures.rate_by_disparity(base, f / "fig6_9b_error.png", groups=("test",), title="Fig. 6.9b error rate")
        figures.rate_bars(base, f / "fig6_9c_correct.png", "Fig. 6.9c correct responses", thesis=thesis)
    dec = base[base["decided"].astype(bool)] if "decided" in base else base
    req = dec.assign(required=(dec["disparity"] / step_deg).round().astype(int))
    per_step = THESIS_TARGETS["cycles per rotation step"].value
    ns = sorted(set(req["required"]))
    figures.rt_by_disparity(req, f / "fig6_9d_steps.png", groups=("test",), x="required",
                            xlabel="rotation steps the disparity requires", ylabel="RT (accumulator cycles)",
                            title="RT against the required rotation steps (decided trials)",
                            thesis={"slightly above 10 n": [(n, per_step * n) for n in ns]} if len(ns) > 1 else None)
    for test, fig in (("recog", "fig6_10"), ("gen1", "fig6_11"), ("custom", "fig6_10_custom")):
        d = df[df["test"] == test]
        if d.empty:
            continue
        figures.rt_by_disparity(d, f / f"{fig}a_rt.png", groups=("condition",), title=f"{test}: RT by proprioception",
                                ylabel="RT (accumulator cycles)")
        figures.rate_by_disparity(d, f / f"{fig}b_error.png", groups=("condition",), title=f"{test}: error rate")
        figures.rate_bars(d, f / f"{fig}c_correct.png", f"{test}: correct responses", by="condition")
    panels = [("recog/none", "fig6_12a_recog"), ("gen1/none", "fig6_12b_gen1"), ("gen2/none", "fig6_12c_gen2"),
              ("recog/match", "fig6_13a_match"), ("recog/mismatch", "fig6_13b_mismatch"),
              ("custom/none", "fig6_12_custom")]
    for key, name in panels:
        hist = histories.get(key)
        if hist:
            pc.sample_panels(f / f"{name}.png", key, hist["trials"], hist["names"], UNITS, hist["why"])


def report(cfg, run, summary) -> None:
    t = summary["tests"]
    r = Report("Experiment 4: generalisation, decision making and embodiment")
    r.chance_warning(summary)
    r.p(f"{summary['participants']} simulated participants; preset `{cfg.preset}`; vision `{cfg.vision.kind}`. "
        "RT in accumulator cycles (10 per rotation step). " + reproducibility_note(cfg.seed))
    _headline(r, t)
    _rt_by_steps(r, cfg, summary)
    r.h("Effects, the participant as the unit")
    r.effects(summary.get("effects", []))
    _statistics(r, summary)
    r.h("Forward models trained on three dots, applied to the test shapes")
    r.table(["set", "IoU after 1 step", "2 steps", "3 steps"],
            [[k, v["1"], v["2"], v["3"]] for k, v in summary["forward_model_iou"].items()])
    e = cfg.experiment
    if cfg.stimuli.kind == "folder":
        r.user_stimuli(summary, cfg.stimuli.path, f"It replaces the Recog set (`recog_set` = {e.recog_set}); the "
                       "Gen1 and Gen2 tests are not run.",
                       f"The forward models are trained on three-dot images and the posture maps C16/C17 on "
                       f"`train_set` = {e.train_set}, as in every run. All conditions (none, match, mismatch, each "
                       "with and without noise) run on your shapes.")
    _differences(r, cfg, t)
    r.h("Figures")
    r.figures(run.root, run.figures.glob("*.png"))
    r.write(run.report_path)


def _headline(r: Report, t: dict) -> None:
    rows = [(f"{k} correct rate", t.get(k, {}).get("correct_rate"), v, True) for k, v in THESIS.items() if k in t]
    rows += [(f"{k} RT-disparity r", t[k]["rt_r"], None, False) for k in ("recog/none", "gen1/none", "gen2/none", "custom/none") if k in t]
    r.h("Headline figures")
    if "custom/none" in t:
        r.p("The thesis has no figures for a user's stimuli: the rows below are this run's alone.")
        rows.insert(0, ("custom/none correct rate", t["custom/none"]["correct_rate"], None, True))
    r.targets(rows)
    r.h("All tests")
    r.table(["test", "trials", "correct", "time-outs (random answer)", "rotated ok", "RT mean", "RT slope/deg", "rt_r"],
            [[k, v["n_trials"], f"{100 * v['correct_rate']:.1f} %", f"{100 * v.get('time_out_rate', 0.0):.1f} %",
              f"{100 * v['rotation_success_rate']:.1f} %",
              v["rt_mean"], v["rt_slope_per_deg"], v["rt_r"]] for k, v in t.items()])


def _rt_by_steps(r: Report, cfg, summary: dict) -> None:
    r.h("RT against the number of rotation steps (thesis: slightly above 10 n)")
    req = summary.get("rt_by_required_steps", {})
    tests_req = [k for k in req if k != "all"]
    r.p("Decided trials of condition none. *Required*: grouped by the steps of "
        f"{cfg.experiment.step_deg:g} deg the pair's disparity requires (disparity / step), the thesis's "
        "measure, overall and per test. *Made*: grouped by the steps the trial itself made; RT counts 10 "
        "cycles per step, so this column lies in (10 n, 10 n + 10] by construction.")
    ns = sorted({int(n) for n in summary["rt_by_rotation_steps"]} | {int(n) for n in req.get("all", {})})
    dash = lambda d, n: d.get(str(n), "-")  # noqa: E731
    r.table(["n", "10 n", "RT, n steps required"] + [f"required, {k}" for k in tests_req] + ["RT, n steps made"],
            [[n, 10 * n, dash(req.get("all", {}), n)] + [dash(req[k], n) for k in tests_req]
             + [dash(summary["rt_by_rotation_steps"], n)] for n in ns])


def _statistics(r: Report, summary: dict) -> None:
    r.h("Embodiment statistics (trials as samples)")
    r.table(["comparison", "RT a", "RT b", "RT p (Welch)", "correct a", "correct b", "correct p"],
            [[k, v["rt"]["mean_a"], v["rt"]["mean_b"], fmt_p(v["rt"]["p"]),
              v["correct"]["rate_a"], v["correct"]["rate_b"], fmt_p(v["correct"]["p"])]
             for k, v in summary["statistics"].items()])
    r.h("Proprioception by disparity, the participant as the unit")
    by = [(k, dsp, v) for k, rows in summary.get("statistics_by_disparity", {}).items() for dsp, v in rows.items()]
    r.p(f"Condition a against b at each disparity: paired t-tests over the participants of their mean RT and "
        f"correct rate (a, b: the means over the participants); p (Holm) corrects over the "
        f"{sum((v['rt_p'] is not None) + (v['correct_p'] is not None) for _, _, v in by)} tests of this table. "
        "Exploratory: the thesis's claims are the effects above.")
    r.table(["comparison", "disparity", "n", "RT a", "RT b", "RT p", "RT p (Holm)", "correct a", "correct b", "correct p",
             "correct p (Holm)"],
            [[k, dsp, v.get("n", "-"), v["rt_a"], v["rt_b"], fmt_p(v["rt_p"]), fmt_p(v.get("rt_p_holm")), v["correct_a"],
              v["correct_b"], fmt_p(v["correct_p"]), fmt_p(v.get("correct_p_holm"))] for k, dsp, v in by])


def _differences(r: Report, cfg, t: dict) -> None:
    e = cfg.experiment
    r.h("Why the numbers differ")
    r.p("Where this run's errors are: " + pc.error_split(t) + ".")
    first = ("The shapes of sets A, B and C are drawn to the design rules of docs/stimuli.md (the thesis's figures "
             "are not in its text); how well the posture maps (C16/C17, trained on set A) read sets B and C, and how "
             "much detail each shape loses under the forward models (IoU table above), set the Gen1 and Gen2 rates."
             if cfg.stimuli.kind != "folder" else
             "How well the posture maps (C16/C17, trained on the built-in training set) read your shapes, and how much "
             "detail each shape loses under the forward models (IoU table above), set the rates on them.")
    r.bullets([
        first,
        "The flipped target (C10) is the target image reflected about the axis of the orientation PPCt reads; "
        "no trial label reaches the model.",
        "PMCd's evidence is the overlap as a fraction of the target's units times a gain (`lca.input_gain`; by "
        "default, per participant, the smallest with which at least 90 % of the identical 0-deg training pairs "
        "decide within one step, rule R1); POCp is read as a population code "
        f"of reach {e.match_tolerance} (`match_tolerance`).",
        "Eq. 6.14 puts a fixed bump on the arg-max posture, which discards the flatter C16 potentials of "
        f"unfamiliar shapes (`posture.tau` = {e.posture.tau}; 0 = arg-max).",
        "docs/choices.md gives the rule behind every constant the thesis does not state and the measured "
        "effect of every departure from the thesis.",
    ])
