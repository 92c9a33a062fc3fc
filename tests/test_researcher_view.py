"""What a researcher reads: figures in the thesis's order with numbered captions, sample trials
chosen to show rotation, statistics with the participant as the unit, and TensorBoard files."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import torch

from neuroimagery.analysis.summary import dz_interval, headline, holm, one_sample, repeated_anova
from neuroimagery.experiments.chapter6 import protocol as pc
from neuroimagery.core.logger import STRIP, TensorBoardLogger
from neuroimagery.core.thesis import EXP3, EXP4, FIGURES, figure_caption, figure_order, is_map_panel


def test_sample_trials_are_chosen_among_the_rotated_and_decided_at_the_largest_disparity():
    t = pd.DataFrame({"disparity": [0, 90, 180, 180, 180, 90, 90], "same": [True, True, False, False, True, False, True]})
    cand = pc.candidate_rows(t, 2)
    assert cand == [4, 2, 3, 1, 6, 5, 0]  # per disparity, largest first: two same and two mirror pairs
    assert pc.candidate_rows(t, 0) == []
    # participant 0: the 180-deg trials never rotated; the 90-deg ones rotated and decided
    rotations = torch.tensor([[0, 2, 0, 0, 0, 3, 1]])
    decided = torch.tensor([[True, True, False, True, False, True, True]])
    chosen, why = pc.choose_samples(t, {"rotations": rotations, "decided": decided}, cand, 2)
    assert [cand[k] for k in chosen] == [1, 5] and why.startswith("participant 0's trials that rotated and decided")
    assert pc.sample_names(t, [cand[k] for k in chosen]) == ["same_90deg", "mirror_90deg"]
    # nothing rotated and decided: the most informative remaining, and the sentence says so
    chosen, why = pc.choose_samples(t, {"rotations": torch.zeros(1, 7, dtype=torch.long), "decided": decided}, cand, 2)
    assert len(chosen) == 2 and "never rotated" in why


def test_figures_come_in_the_thesis_order_with_numbered_captions():
    stems = ["fig6_11a_rt", "fig6_9c_correct", "fig6_10b_error", "fig6_9a_rt", "fig6_12a_recog", "fig5_5a_rt"]
    assert sorted(stems, key=figure_order) == ["fig5_5a_rt", "fig6_9a_rt", "fig6_9c_correct", "fig6_10b_error",
                                                "fig6_11a_rt", "fig6_12a_recog"]
    c = figure_caption("fig6_9c_correct", 3, "Error bars: SEM over participants")
    assert c.startswith("Figure 3. (Fig. 6.9c)") and "SEM over participants" in c and "79 %" in c
    assert c.endswith("(section 6.2.3).")
    assert is_map_panel("fig6_12a_recog") and not is_map_panel("fig6_9a_rt")
    assert all(f.line > 0 and f.states for f in FIGURES.values())
    # the stated values are those the reports compare with
    assert EXP3["gen2/none error rate"].value == 0.543 and EXP4["recog/none correct rate"].value == 0.79


def test_effect_size_interval_matches_its_large_sample_approximation():
    rng = np.random.default_rng(0)
    v = rng.normal(0.5, 1.0, 400)
    d, (lo, hi) = dz_interval(v)
    half = 1.96 * math.sqrt(1 / v.size + d * d / (2 * v.size))
    assert lo < d < hi
    assert lo == pytest.approx(d - half, abs=0.01) and hi == pytest.approx(d + half, abs=0.01)
    res = one_sample(v)
    assert res["ci95"][0] < res["mean"] < res["ci95"][1] and res["p"] < 1e-6


def test_holm_correction_over_a_family():
    rows = [{"p": 0.01, "expected": ">0", "value": 1.0, "holds": True},
            {"p": 0.04, "expected": ">0", "value": 1.0, "holds": True},
            {"p": 0.03, "expected": ">0", "value": 1.0, "holds": True}]
    out = holm(rows)
    assert [r["p_holm"] for r in out] == pytest.approx([0.03, 0.06, 0.06])
    assert [r["holds"] for r in out] == [True, False, False]


def test_holm_adjusted_p_values_are_statsmodels_bit_for_bit():
    from statsmodels.stats.multitest import multipletests

    from neuroimagery.analysis.summary import holm_adjusted

    r = np.random.default_rng(0)
    for n in (1, 2, 7, 60):
        p = r.random(n) ** 3
        p[r.integers(0, n, n // 3)] = p[0]  # ties
        p[-1] = 1.0
        assert np.array_equal(holm_adjusted(p), multipletests(p, method="holm")[1])


def test_repeated_measures_anova_finds_a_within_participant_effect():
    rng = np.random.default_rng(1)
    rows = [{"participant": p, "kind": k, "rt": 10 + 3 * (k == "b") + rng.normal(0, 0.5) + p}
            for p in range(8) for k in ("a", "b", "c") for _ in range(4)]
    res = repeated_anova(pd.DataFrame(rows), "kind")
    assert res["n"] == 8 and res["df"] == [2, 14] and res["p"] < 1e-6


def test_headline_takes_per_test_figures():
    s = {"participants": 10, "tests": {"recog/none": {"correct_rate": 0.8, "rt_mean": 40.0, "n_trials": 5}}}
    assert headline(s) == {"participants": 10, "recog/none/correct_rate": 0.8, "recog/none/rt_mean": 40.0}


def _accumulate(root):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    ea = EventAccumulator(str(root), size_guidance={"images": 0, "scalars": 0})
    ea.Reload()
    return ea


def test_tensorboard_one_event_file_readable_strips_and_hparams(tmp_path):
    for _ in range(2):  # a run rewritten into its directory
        lg = TensorBoardLogger(tmp_path)
        for s in range(3):
            lg.map("sample/PMCm", torch.tensor([0.0, 1.0, 0.5]), step=s + 1)
        lg.hparams({"seed": 0, "experiment.eta": 0.1, "experiment.sets": [1, 2]}, {"recog/correct_rate": 0.7})
        lg.close()
    assert len(list(tmp_path.glob("events.out.tfevents.*"))) == 1
    ea = _accumulate(tmp_path)
    img = ea.Images("sample/PMCm")
    assert [e.step for e in img] == [1, 2, 3]
    assert img[0].width % 3 == 0 and img[0].width // 3 >= STRIP and img[0].height == STRIP  # one cell per unit
    assert {"_hparams_/experiment", "_hparams_/session_start_info"} <= set(ea.PluginTagToContent("hparams"))
    assert [e.value for e in ea.Scalars("values/recog/correct_rate")] == pytest.approx([0.7])
    assert "summary/headline/text_summary" in ea.Tags()["tensors"]


def test_tensorboard_scalars_are_curves_and_single_values_go_to_text(tmp_path):
    lg = TensorBoardLogger(tmp_path)
    for s in range(4):
        lg.scalar("train/C1/squared_error", 1.0 / (s + 1), s)
    lg.scalar("train/C1/weight_norm_final", 2.5, 4)
    lg.scalar("recog/none/correct_rate", 0.8)
    lg.hparams({"seed": 0}, {"recog/none/correct_rate": 0.8})
    lg.close()
    ea = _accumulate(tmp_path)
    scalars = ea.Tags()["scalars"]
    assert [e.step for e in ea.Scalars("train/C1/squared_error")] == [0, 1, 2, 3]  # the held first point too
    assert all(len(ea.Scalars(t)) > 1 for t in scalars if not t.startswith("values/")), scalars
    assert "train/C1/weight_norm_final" not in scalars and "recog/none/correct_rate" not in scalars
    text = ea.Tensors("summary/single_values/text_summary")[0].tensor_proto.string_val[0].decode()
    assert "train/C1/weight_norm_final" in text and "2.5" in text and "recog/none/correct_rate" in text


@pytest.mark.parametrize("method", ["online", "factored"])
def test_som_training_curve_falls_and_reports_the_final_state(method):
    from neuroimagery.nn import SOM, monitor

    g = torch.Generator().manual_seed(0)
    X = torch.rand(40, 16, generator=g)
    som = SOM((6, 6), 16, participants=2, seed=1, eta=0.3, iterations=400, sigma=2.0, name="test")
    seen = []
    with monitor.to(lambda tag, v, step: seen.append((tag, v, step))):
        som.fit(X, method=method)
    curve = [(s, v) for t, v, s in seen if t == "train/som/test/winner_distance"]
    assert len(curve) == 100 and curve[-1][0] == 400
    assert np.mean([v for _, v in curve[-10:]]) < 0.8 * np.mean([v for _, v in curve[:10]])
    finals = {t for t, _, s in seen if s == 400 and t.endswith("_final")}
    assert finals == {"train/som/test/quantisation_error_final", "train/som/test/topographic_error_final"}
    seen.clear()
    SOM((6, 6), 16, participants=2, seed=1, iterations=50).fit(X)  # no reader: nothing measured
    assert seen == [] and not monitor.active()


@pytest.mark.parametrize("method", ["delta_binary", "plain"])
def test_forward_model_training_curve_falls(method):
    from neuroimagery.nn import AllToAll, Delta, monitor

    g = torch.Generator().manual_seed(0)
    X = (torch.rand(1, 400, 30, generator=g) < 0.2).float()
    Y = X.roll(1, dims=-1)  # a learnable map: each unit copies its neighbour
    conn = AllToAll(30, 30, participants=1, generators=[torch.Generator().manual_seed(1)], rules=Delta(0.1),
                    name="C1")
    seen = []
    with monitor.to(lambda tag, v, step: seen.append((tag, v, step))):
        conn.learn(X, sequence=True, batch=4, method=method, target=Y)
    curve = [v for t, v, _ in seen if t == "train/C1/squared_error"]
    assert len(curve) == 100
    assert np.mean(curve[-10:]) < 0.2 * np.mean(curve[:10])
    final = {t: (v, s) for t, v, s in seen if t.endswith("_final")}
    assert final["train/C1/weight_max_final"] == (pytest.approx(float(conn.weight.max())), 400)
    assert final["train/C1/weight_norm_final"][0] == pytest.approx(float(conn.weight[0].norm()))


def _robots(rise: float, planning_gap: float, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for rep in range(30):
        for lvl in (2, 3, 4, 5, 6):
            base = rng.random()
            for strat in ("reactive", "planning"):
                p = min(1.0, max(0.0, 0.1 + rise * (lvl - 2) - (planning_gap if strat == "planning" else 0.0)))
                rows.append(dict(individual=f"rep{rep}_far", library=f"rep{rep}", hypothesis="hp1", level=lvl,
                                 situation="far", strategy=strat, success=int(base < p)))
    return pd.DataFrame(rows)


def test_robot_effects_find_a_rise_with_age_and_alike_strategies():
    from neuroimagery.analysis.robots import effects

    eff = effects(_robots(0.15, 0.0), [2, 3, 4, 5, 6], [])
    rise = [e for e in eff if e["effect"].startswith("HP1 tool far rises")]
    assert len(rise) == 2 and all(e["value"] > 0 and e["holds"] and e["n"] == 30 for e in rise), rise
    alike = next(e for e in eff if e["effect"].startswith("reactive and planning"))
    assert alike["value"] == 0 and alike["holds"]  # the same robots answer alike both ways
    flat = effects(_robots(0.0, 0.3), [2, 3, 4, 5, 6], [])
    assert not any(e["holds"] for e in flat if e["effect"].startswith("HP1"))
    gap = next(e for e in flat if e["effect"].startswith("reactive and planning"))
    assert gap["value"] > 0.05 and gap["p_difference"] < 1e-3 and not gap["holds"]  # reactive 10 %, planning 0 %
    assert gap["p"] > 0.05 and gap["bound"] == 0.05  # not equivalent within 5 points


def test_exp5_training_curves_average_each_event_over_its_skills():
    from neuroimagery.experiments.exp5.figures import training_curves

    lib = lambda *skills: {"library": {"skills": list(skills)}}  # noqa: E731
    sk = lambda ev, signals, comp: {"event": ev, "log": [("c1", 1, s) for s in signals] + [("c23", 1, None)],  # noqa: E731
                                    "competence": comp}
    c = training_curves([lib(sk("pull", [0.0, 0.5], [0.2, 0.6])), lib(sk("pull", [1.0], [0.4]), sk("touch", [0.25], [1.0]))])
    assert c["pibb/pull/cost"] == pytest.approx([0.5, 0.5]) and c["competence/pull"] == pytest.approx([0.3, 0.6])
    assert c["pibb/touch/cost"] == pytest.approx([0.75]) and set(c) == {"pibb/pull/cost", "competence/pull",
                                                                         "pibb/touch/cost", "competence/touch"}


def test_exp5_sequencing_curves_follow_the_training_trials():
    from neuroimagery.experiments.exp5.figures import sequencing_curves

    df = pd.DataFrame([
        dict(hypothesis="hp2", training_trials=2, situation="far", strategy="reactive", train_successes="0>1",
             train_q="0>0.5"),
        dict(hypothesis="hp2", training_trials=4, situation="far", strategy="reactive", train_successes="1>1>0>1",
             train_q="0.5>0.7>0.6>0.9"),
        dict(hypothesis="hp2", training_trials=0, situation="far", strategy="reactive", train_successes="",
             train_q=""),
        dict(hypothesis="hp1", training_trials=10, situation="far", strategy="reactive", train_successes="1",
             train_q="9")])
    c = sequencing_curves(df)
    assert c["sequencing/far/reactive/success"] == pytest.approx([0.5, 1.0, 0.0, 1.0])
    assert c["sequencing/far/reactive/q_max"] == pytest.approx([0.25, 0.6, 0.6, 0.9])


def test_tost_matches_statsmodels_and_decides_equivalence_by_the_bound():
    from statsmodels.stats.weightstats import DescrStatsW

    from neuroimagery.analysis.summary import effect, tost

    rng = np.random.default_rng(3)
    v = rng.normal(0.3, 2.0, 12)
    for bound in (0.5, 2.0, 5.0):
        want = DescrStatsW(v).ttost_mean(-bound, bound)[0]
        assert tost(float(v.mean()), float(v.std(ddof=1)), v.size, bound) == pytest.approx(want, rel=1e-9)
    small, wide = one_sample(rng.normal(0.0, 0.2, 20)), one_sample(rng.normal(0.0, 20.0, 20))
    small["diff"], wide["diff"] = small.pop("mean"), wide.pop("mean")
    tight = effect("flat", "~0", small, bound=1.0)
    assert tight["holds"] and tight["p"] < 0.05 and tight["bound"] == 1.0
    loose = effect("flat", "~0", wide, bound=1.0)  # a large p of the difference test is not "no effect"
    assert loose["p_difference"] > 0.05 and loose["p"] > 0.05 and not loose["holds"]
    assert effect("flat", "~0", small)["holds"] is None  # no bound: not tested
    rows = holm([tight, loose])
    assert rows[0]["holds"] and not rows[1]["holds"]


def test_degenerate_spread_is_flagged_and_said_in_the_report():
    from neuroimagery.analysis.report import Report
    from neuroimagery.analysis.summary import effect

    near_copies = one_sample(np.array([2.0, 2.01, 1.99, 2.0, 2.005]))
    near_copies["diff"] = near_copies.pop("mean")
    row = holm([effect("RT rises", ">0", near_copies)])[0]
    assert row["d_z"] > 10 and row["d_z_degenerate"] and row["holds"]
    text = Report("t").effects([row]).text()
    assert "(degenerate)" in text and "initial weights" in text
    spread = one_sample(np.array([2.0, 1.0, 3.0, 2.5, 1.5]))
    spread["diff"] = spread.pop("mean")
    assert not effect("RT rises", ">0", spread)["d_z_degenerate"]


def test_markdown_check_finds_what_breaks_a_report():
    from support_markdown import markdown_problems

    from neuroimagery.analysis.report import Report

    bad = ("# x\n\n| a | b |\n|---|---|\n| RT rises with |disparity| | 1 |\n\n- recognition/none: \n\n"
           "| c | p |\n|---|---|\n| y | 0 |\n\np = 0 here\n")
    found = markdown_problems(bad)
    assert len(found) == 4, found
    good = (Report("x").table(["effect", "p"], [["RT rises with |disparity|", "< 1e-16"]])
            .bullets(["", "recognition/none: none"]).text())
    assert markdown_problems(good) == [] and "\\|disparity\\|" in good
