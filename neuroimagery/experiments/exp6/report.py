"""Experiment 6 results: ``summary.json``, figures (RT against angle as Shepard & Metzler's Fig. 2,
error rates, the stimuli, per-step map projections), TensorBoard image series and ``report.md``."""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ...analysis import figures
from ...analysis.report import Report, reproducibility_note
from ...analysis.summary import effect, holm, one_sample, paired_by_participant, slope_by_participant, summarise_trials
from .config import TESTS

# Shepard & Metzler (1971), Fig. 2 and text: same-pair RT linear in angle, r about 0.97 in both
# conditions; slopes nearly equal; about 1 s per 50-60 deg (here 55 deg: 18.2 ms per deg)
HUMAN = {"rt_r": 0.97, "ms_per_deg": 1000.0 / 55.0, "error_rate": 0.03}
GOALS = {"rt_r": 0.9, "slope_within": 0.25, "correct_rate": 0.75, "mirror_different_rate": 0.70}
SLOPE_LABEL = "slopes alike: picture plane minus depth (per participant)"


def slope_bound(cycles: float = 10.0, step_deg: float = 20.0) -> float:
    """The equivalence bound of "slopes alike" (docs/choices.md): ``slope_within`` (25 %, from
    Shepard & Metzler's 50-60 deg per second) of the nominal rate of rotation, ``cycles`` RT cycles
    per step of ``step_deg`` (the protocol's units, not the slopes compared)."""
    return GOALS["slope_within"] * float(cycles) / float(step_deg)


def _fit(x, y) -> dict:
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2 or np.ptp(x) == 0:
        return {"slope": None, "intercept": None, "r": None}
    if np.ptp(y) == 0:
        return {"slope": 0.0, "intercept": float(y[0]), "r": None}
    f = stats.linregress(x, y)
    return {"slope": round(float(f.slope), 5), "intercept": round(float(f.intercept), 4), "r": round(float(f.rvalue), 4)}


def same_pair_rt(df: pd.DataFrame) -> dict:
    """Shepard & Metzler's measure: mean RT of the correctly answered same pairs at each angle, and
    its least-squares line and Pearson r against angle (all same pairs given too)."""
    out = {}
    for label, d in (("correct", df[df["same"].astype(bool) & df["correct"].astype(bool)]),
                     ("all", df[df["same"].astype(bool)])):
        g = d.groupby("disparity")["rt"].mean().sort_index()
        f = _fit(g.index, g.values)
        out[label] = {"n": int(len(d)), "rt_by_angle": {str(int(k)): round(float(v), 3) for k, v in g.items()},
                      "rt_slope_per_deg": f["slope"], "rt_intercept": f["intercept"], "rt_r": f["r"]}
    return out


def effects(df: pd.DataFrame, bound: float | None = None) -> list[dict]:
    """Shepard & Metzler's effects, each with the participant as the unit (Holm over the family):
    RT of correct same pairs rises with angle in each kind of rotation, the two slopes alike
    (equivalence within ``bound``, :func:`slope_bound` of the defaults when None), and the correct
    rate above chance; then the proprioception effects where the trials have other wrist
    conditions than ``none`` (Shepard & Metzler's own on ``none`` only)."""
    bound = slope_bound() if bound is None else bound
    if set(df["condition"]) - {"none"}:
        return effects(df[df["condition"] == "none"], bound) + proprioception_effects(df)
    ok = df[df["same"].astype(bool) & df["correct"].astype(bool)]
    by = {t: ok[ok["test"] == t] for t in ("picture", "depth") if (ok["test"] == t).any()}
    rows = [effect(f"{t}: RT of correct same pairs rises with angle", ">0", slope_by_participant(d), "mean_slope")
            for t, d in by.items()]
    if len(by) == 2:
        per = {t: {p: np.polyfit(g["disparity"], g["rt"], 1)[0] for p, g in d.groupby("participant")
                   if g["disparity"].nunique() > 1} for t, d in by.items()}
        both = sorted(set(per["picture"]) & set(per["depth"]))
        res = one_sample([per["picture"][p] - per["depth"][p] for p in both])
        res["diff"] = res.pop("mean")
        rows.append(effect(SLOPE_LABEL, "~0", res, bound=bound))
    res = one_sample(df.assign(c=df["correct"].astype(float)).groupby("participant")["c"].mean() - 0.5)
    res["diff"] = res.pop("mean")
    rows.append(effect("correct rate above chance (rate minus 0.5)", ">0", res))
    return holm(rows)


def proprioception_effects(df: pd.DataFrame) -> list[dict]:
    """The Exp 4 wrist conditions carried over, each against ``none`` with the participant as the
    unit (Holm over the family): a congruent wrist signal (``match``) shortens the RT of correct
    same pairs, an incongruent one (``mismatch``) lengthens it, as in Exp 4."""
    ok = df[df["same"].astype(bool) & df["correct"].astype(bool)]
    rows = []
    for test in [t for t in TESTS if t in set(df["test"])]:
        base = ok[(ok["test"] == test) & (ok["condition"] == "none")]
        for cond, sign in (("match", "<0"), ("mismatch", ">0")):
            d = ok[(ok["test"] == test) & (ok["condition"] == cond)]
            if len(d) and len(base):
                rows.append(effect(f"{test}: RT of correct same pairs, {cond} minus none", sign,
                                   paired_by_participant(d, base, "rt")))
    return holm(rows)


def headline(tests: dict, df: pd.DataFrame, rows: list[dict] | None = None) -> dict:
    """The measures the goals name, and whether each goal is met ("slopes alike": the
    equivalence test of the effects ``rows``, the same test the effects table reports)."""
    slopes = {k: v["same_pairs"]["correct"]["rt_slope_per_deg"] for k, v in tests.items()}
    rs = {k: v["same_pairs"]["correct"]["rt_r"] for k, v in tests.items()}
    s = [v for v in slopes.values() if v is not None]
    ratio = round(min(s) / max(s), 4) if len(s) == 2 and max(s) > 0 and min(s) > 0 else None
    diff = round(abs(s[0] - s[1]) / max(abs(s[0]), abs(s[1])), 4) if len(s) == 2 and max(map(abs, s)) > 0 else None
    mirror = df[~df["same"].astype(bool)]
    alike = [e for e in rows or [] if e["effect"] == SLOPE_LABEL]
    h = {"rt_r": rs, "rt_slope_per_deg": slopes, "slope_ratio": ratio, "slope_difference": diff,
         "correct_rate": round(float(df["correct"].mean()), 4),
         "mirror_different_rate": round(float((mirror["answer"] == "no").mean()), 4) if len(mirror) else None,
         "same_yes_rate": round(float((df[df["same"].astype(bool)]["answer"] == "yes").mean()), 4),
         "decided_rate": round(float(df["decided"].mean()), 4)}
    h["goals"] = {"rt_r_at_least_0.9": all(v is not None and v >= GOALS["rt_r"] for v in rs.values()),
                  "slopes_alike": bool(alike and alike[0]["holds"]) and min(s, default=0) > 0,
                  "correct_at_least_75_percent": h["correct_rate"] >= GOALS["correct_rate"],
                  "mirror_different_at_least_70_percent": (h["mirror_different_rate"] or 0) >= GOALS["mirror_different_rate"]}
    return h


def summarise(run, trained, df: pd.DataFrame, histories: dict, stages: dict) -> dict:
    """``summary.json`` of the tests' rows ``df`` and the stage measures, with the figures and the
    TensorBoard series of the sample trials' ``histories``."""
    tests = summarise_trials(df)
    still = df[df["condition"] == "none"]  # Shepard & Metzler's measures: the wrist kept still
    for key, v in tests.items():
        d = df[(df["test"] + "/" + df["condition"]) == key]
        g = d.groupby("disparity")["rt"].mean().sort_index()
        v["rt_intercept"] = _fit(g.index, g.values)["intercept"]
        v["same_pairs"] = same_pair_rt(d)
        v["mirror_different_rate"] = round(float((d[~d["same"].astype(bool)]["answer"] == "no").mean()), 4)
    side = trained.side
    shepard = {k: v for k, v in tests.items() if k.split("/")[0] in ("picture", "depth") and k.endswith("/none")}
    e = run.cfg.experiment if getattr(run, "cfg", None) is not None else None
    rows = effects(df, slope_bound(e.lca.cycles, e.step_deg) if e is not None else None)
    summary = {"experiment": "exp6", "participants": int(df["participant"].nunique()), "tests": tests,
               "targets": {k: {"rt_r": HUMAN["rt_r"]} for k in shepard},  # Shepard & Metzler's r, each kind of rotation
               "headline": headline(shepard, still[still["test"].isin(["picture", "depth"])], rows),
               "effects": rows, "human": HUMAN, "goals": GOALS, "stages": stages,
               "grid": trained.describe()}
    for key, hist in histories.items():
        log_history(run.logger, hist, key, side)
    for key, v in tests.items():
        run.logger.scalars({"correct_rate": v["correct_rate"], "rt_mean": v["rt_mean"]}, prefix=f"{key}/")
    _figures(run, still, histories, side)
    return summary


def _projections(step: dict, side: int, names=("PFCt", "POCp")) -> dict:
    from ...models import voxels

    out = {}
    for n in names:
        for view, img in voxels.projections(step[n], side).items():
            out[f"{n}_{view}"] = img
    return out


def log_history(logger, history, prefix: str, side: int) -> None:
    """Three orthogonal projections of every 3-D map, and PMCm / PMCd, at every step of each sample
    trial (``history``: ``{"steps": [trial][step] maps, "trials": [what each trial is]}``)."""
    for k, steps in enumerate(history["steps"]):
        for s, st in enumerate(steps):
            maps = _projections(st, side)
            maps["PMCm"] = st["PMCm"]
            if "PMCd" in st:
                maps["PMCd"] = st["PMCd"]
            logger.maps(maps, step=s + 1, prefix=f"{prefix}/trial{k}/")


def _fig2(df: pd.DataFrame, path, tests) -> None:
    """Mean RT of correct same pairs against angle, one panel per rotation kind, with the line."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(tests), figsize=(4.2 * len(tests), 3.6), squeeze=False, sharey=True)
    for ax, test in zip(axes[0], tests):
        d = df[(df["test"] == test) & df["same"].astype(bool) & df["correct"].astype(bool)]
        per = d.groupby(["disparity", "participant"])["rt"].mean().unstack()
        m = d.groupby("disparity")["rt"].mean().sort_index()  # over the trials, as summary.json's same_pairs
        sem = (per.std(axis=1, ddof=1) / np.sqrt(per.notna().sum(axis=1))).reindex(m.index) if per.shape[1] > 1 else 0 * m
        ax.errorbar(m.index, m.values, yerr=np.nan_to_num(np.asarray(sem, float)), marker="o", capsize=3, color="k")
        f = _fit(m.index, m.values)
        if f["slope"] is not None:
            xs = np.array([0, 180])
            ax.plot(xs, f["intercept"] + f["slope"] * xs, "--", color="grey",
                    label=f"{f['slope']:.3g} cycles/deg, r = {f['r'] if f['r'] is not None else '-'}")
            ax.legend(fontsize=8, loc="upper left")
        ax.set_title({"picture": "picture-plane pairs", "depth": "depth pairs"}.get(test, f"{test} pairs"))
        ax.set_xlabel("angle of rotation (deg)")
        ax.set_xticks(range(0, 181, 40))
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("mean RT, correct 'same' (cycles)")
    fig.text(0.5, 0.01, "error bars: s.e.m. over participants", fontsize=8, ha="center")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    figures.save(fig, path)


@figures.timed
def _figures(run, df, histories, side) -> None:
    f = run.figures
    tests = [t for t in TESTS if t in set(df["test"])]
    _fig2(df, f / "exp6_fig2_rt.png", tests)
    figures.rate_by_disparity(df.assign(kind=np.where(df["same"], "same", "mirror")), f / "exp6_error.png",
                              groups=("test", "kind"), title="error rate by angle")
    for key, hist in histories.items():
        if hist["steps"] and hist["steps"][0]:
            test, cond = key.split("/")
            sample_figure(hist["steps"][0], hist["trials"][0], test, cond, side,
                          f / f"exp6_maps_{test}{'' if cond == 'none' else '_' + cond}.png")


def _move_name(pmcm) -> str:
    """The move a step's PMCm (one-hot over the moves) chose: 'still' or e.g. 'turn about z, -'."""
    from ...models.rotation_3d import MOVES

    m = MOVES[int(np.argmax(np.asarray(pmcm)))]
    return m if m == "still" else f"turn {m[0]}{m[1]}"


def sample_figure(steps: list, trial: dict, test: str, cond: str, side: int, path) -> None:
    """Every step of one sample trial: the target (PFCt) and the comparison as the mental rotation
    turns it (POCp), each seen from the front, the top and the side; a row per step, labelled with
    the move PMCm chose."""
    keep = ("PFCt_front", "PFCt_top", "POCp_front", "POCp_top", "POCp_side")
    rows = [{k: v.numpy() for k, v in _projections(st, side).items() if k in keep} for st in steps]
    kind = {"picture": "in the picture plane", "depth": "in depth"}.get(test, f"({test})")
    pair = "same pair" if bool(trial["same"]) else "mirror pair"
    wrist = "" if cond == "none" else f", wrist signal {cond}"
    figures.map_panels(
        rows, path, title=f"Sample trial: {trial['target_object']}, {pair} turned {float(trial['rotated_angle']):g} deg "
        f"{kind}{wrist}; {'its one step' if len(steps) == 1 else f'all {len(steps)} steps'} of the mental rotation "
        "(maps seen from front, top, side)",
        row_labels=[f"step {i + 1}: {_move_name(st['PMCm'])}" for i, st in enumerate(steps)])


WRIST_NOTE = ("Wrist conditions (Exp 4's, carried over): the wrist signal, the rotation it has done about the line of "
              "sight (relative, as in Wexler et al. 1998), joins PPCp, on the value the mental rotation has reached "
              "(`match`) or on its opposite (`mismatch`); as in Exp 4, a congruent signal is expected to shorten and an "
              "incongruent one to lengthen the RT (rows 'match minus none' and 'mismatch minus none' above; the "
              "measures beside Shepard & Metzler use `none`).")
DIFFERENCES = [
    "One view gives a surface; the completion map fills in hidden cubes only as far as chains taught it, so depth "
    "pairs, whose two views show different faces, start from less alike images than picture-plane pairs.",
    "The transform turns about the camera axes in steps of a fixed size; the last step leaves up to half a step, and "
    "the chained steps blur the image, which the mismatch cluster must tolerate.",
    "RT is counted in accumulator cycles; Shepard & Metzler's seconds include encoding and response time.",
]


def report(cfg, run, summary) -> None:
    e = cfg.experiment
    r = Report("Experiment 6: 3-D mental rotation of Shepard-Metzler objects")
    r.p(f"{summary['participants']} simulated participants; preset `{cfg.preset}`; objects seen by the iCub's "
        f"{e.view.eye} eye (pybullet, colour + depth). RT in accumulator cycles (10 per rotation step of {e.step_deg:g} deg). "
        + reproducibility_note(cfg.seed))
    _beside_humans(r, summary)
    r.h("Effects, the participant as the unit")
    r.effects(summary.get("effects", []))
    if set(e.conditions) - {"none"}:
        r.p(WRIST_NOTE)
    _all_tests(r, summary["tests"])
    _stages(r, e, summary)
    r.h("Why the numbers differ from the human data")
    r.bullets(DIFFERENCES)
    r.h("Figures")
    for p in sorted(run.figures.glob("*.png")):
        r.figure(p, caption(p.stem), root=run.root)
    r.write(run.report_path)


def _beside_humans(r: Report, summary: dict) -> None:
    t, h = summary["tests"], summary["headline"]
    r.h("Beside Shepard & Metzler (1971)")
    bound = next((x["bound"] for x in summary.get("effects", []) if x["effect"] == SLOPE_LABEL), None)
    r.p("Human values: mean RT of correct 'same' answers linear in the angle, r about 0.97 for both kinds of "
        "rotation, nearly equal slopes (about 1 s per 50-60 deg), few errors (about 3 %). Goals of this "
        "experiment: r >= 0.9 in each condition, slopes alike (the participants' picture-plane minus depth "
        "slopes equivalent to 0 within 25 % of the nominal rate of rotation, the effects table's test; "
        "docs/choices.md), at least 75 % correct, mirror pairs answered 'different' at least 70 %.")
    rows = []
    for k in ("picture/none", "depth/none"):
        if k in t:
            sp = t[k]["same_pairs"]["correct"]
            rows.append([k, sp["n"], sp["rt_r"], sp["rt_slope_per_deg"], sp["rt_intercept"], "0.97"])
    r.table(["test", "correct same trials", "r (RT vs angle)", "slope (cycles/deg)", "intercept (cycles)", "human r"], rows)
    g = h["goals"]
    r.table(["measure", "this run", "goal", "met"],
            [["slopes alike (equivalence, effects table)", f"|a - b| / max = {h['slope_difference']}",
              "-" if bound is None else f"difference within ±{bound:.3g} cycles/deg", _yes(g["slopes_alike"])],
             ["correct, all trials", f"{100 * h['correct_rate']:.1f} %", ">= 75 %", _yes(g["correct_at_least_75_percent"])],
             ["mirror pairs answered 'different'", "-" if h["mirror_different_rate"] is None else f"{100 * h['mirror_different_rate']:.1f} %",
              ">= 70 %", _yes(g["mirror_different_at_least_70_percent"])],
             ["r >= 0.9 in both conditions", ", ".join(f"{k.split('/')[0]} {v if v is not None else '-'}"
                                                       for k, v in h["rt_r"].items()), ">= 0.9", _yes(g["rt_r_at_least_0.9"])],
             ["same pairs answered 'same'", f"{100 * h['same_yes_rate']:.1f} %", "-", "-"],
             ["trials decided within 20 steps", f"{100 * h['decided_rate']:.1f} %", "-", "-"]])


def _all_tests(r: Report, t: dict) -> None:
    r.h("All tests")
    r.table(["test", "trials", "correct", "rotated to the target", "RT mean", "RT slope/deg (all)", "rt_r (all)", "mirror 'different'"],
            [[k, v["n_trials"], f"{100 * v['correct_rate']:.1f} %", f"{100 * v['rotation_success_rate']:.1f} %",
              v["rt_mean"], v["rt_slope_per_deg"], v["rt_r"], f"{100 * v['mirror_different_rate']:.1f} %"] for k, v in t.items()])
    r.h("Mean RT of correct same pairs by angle (cycles)")
    angles = sorted({int(a) for v in t.values() for a in v["same_pairs"]["correct"]["rt_by_angle"]})
    r.table(["test"] + [str(a) for a in angles],
            [[k] + [v["same_pairs"]["correct"]["rt_by_angle"].get(str(a), "-") for a in angles] for k, v in t.items()])


def _stages(r: Report, e, summary: dict) -> None:
    r.h("The model: each stage against its contract (docs/contracts.md)")
    gr, st = summary["grid"], summary["stages"]
    r.bullets([
        f"3-D map {gr['side']}^3 voxels (grid rule, `fm.memory_mb`), {gr['cube_voxels']:.3g} voxels per cube edge; forward "
        f"models with receptive-field radius {gr['receptive_radius']} ({gr['offsets']} weights per voxel, "
        f"{gr['fm_mb_per_participant']} MB per participant for the {gr['moves']} models). Strategy `{e.strategy}`.",
        f"6.1 image: completed map of held-out chains against the whole volume, cosine {st['image']['cosine']} "
        f"(the seen surface alone {st['image']['surface_cosine']}; contract >= 0.85).",
        f"6.2 transform: {st['transform']['steps']} chained steps against one turn, cosine "
        + ", ".join(f"{k} {v:.3f}" for k, v in st["transform"]["cosine"].items())
        + f" (contract >= 0.8); same above mirror in {100 * st['transform']['same_above_mirror']:.0f} % (contract >= 90 %).",
        f"6.3 search: rotation within 20 deg in {100 * st['search']['picture']:.0f} % of picture-plane and "
        f"{100 * st['search']['depth']:.0f} % of depth pairs of held-out chains (contract >= 95 % / >= 85 %).",
        f"6.3b search precision: estimate within half a step of the true alignment in "
        + ", ".join(f"{lab} {k} {100 * v:.0f} %" for lab in ("train", "held_out") for k, v in st["precision"][lab].items())
        + " of same pairs (contract >= 90 % each).",
        f"6.2c transform: net turn within half a step of the estimate in "
        + ", ".join(f"{lab} {k} {100 * v:.0f} %" for lab in ("train", "held_out") for k, v in st["realisation"][lab].items())
        + " of same pairs (contract >= 90 % each).",
        f"6.4 confirm: the cut ({st['confirm']['cut_cubes']} cubes) puts {100 * st['confirm']['train']:.0f} % of the training "
        f"objects' pairs and {100 * st['confirm']['held_out']:.0f} % of held-out chains' pairs on their side (contract >= 90 % each).",
        "The rotation required, each step and the answer come from the two images alone (no trial label reaches the model).",
    ])


def _yes(v) -> str:
    return "yes" if v else "**no**"


def caption(stem: str) -> str:
    """What a figure of the run shows (by its file's stem)."""
    fixed = {
        "exp6_fig2_rt": "Mean RT of correct 'same' answers against the angle of rotation, picture plane and depth "
                        "(as Shepard & Metzler's Fig. 2), with the least-squares line; error bars: s.e.m. over participants.",
        "exp6_error": "Error rate by angle, same and mirror pairs, each kind of rotation.",
        "exp6_stimuli": "The objects of this run (training objects, then the test objects) as the iCub's eye sees them "
                        "in the general view.",
    }
    if stem in fixed:
        return fixed[stem]
    if stem.startswith("exp6_maps_"):
        test, _, cond = stem.removeprefix("exp6_maps_").partition("_")
        kind = {"picture": "picture-plane", "depth": "depth"}.get(test, test)
        wrist = f" (wrist signal {cond})" if cond else ""
        return (f"One {kind} sample trial{wrist}, every step: the target (PFCt) and the comparison as the mental "
                "rotation turns it (POCp), each map projected from the front, top and side; a row per step, "
                "labelled with the move PMCm chose.")
    return stem.replace("_", " ")
