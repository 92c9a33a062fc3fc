"""What a researcher opens first: figures whose texts do not overlap, step-by-step mosaics that
say what each unit is, a user's stimulus folder with a report of its own, and TensorBoard on a
fresh Exp 4 run with curves only among its scalars and every rotation step of its sample trials.
(Every report.md written here also passes the Markdown check of conftest.py.)"""
from __future__ import annotations

import cv2
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from support_figures import checking_overlaps, text_overlaps

from conftest import make_cfg
from neuroimagery.analysis import figures
from neuroimagery.config import validate
from neuroimagery.app.run import evaluate

CONDITIONS = ["none", "match", "mismatch", "noise-none", "noise-match", "noise-mismatch"]


def _conditions_frame():
    rng = np.random.default_rng(0)
    return pd.DataFrame([{"participant": p, "condition": c, "correct": bool(rng.random() < 0.6), "disparity": d,
                          "rt": 10.0 + d / 10, "test": "custom"}
                         for p in range(2) for c in CONDITIONS for d in (0, 90, 180)])


def test_long_condition_names_under_narrow_bars_do_not_overlap(tmp_path):
    df = _conditions_frame()
    fig, ax = plt.subplots(figsize=(5, 3.5))  # the check finds the overlap a plain layout leaves
    ax.bar(range(6), [1] * 6)
    ax.set_xticks(range(6), CONDITIONS)
    fig.tight_layout()
    fig.canvas.draw()
    assert any("noise-" in o for o in text_overlaps(fig))
    plt.close(fig)
    with checking_overlaps() as found:
        figures.rate_bars(df, tmp_path / "c.png", "custom: correct responses", by="condition")
        figures.rate_by_disparity(df, tmp_path / "b.png", groups=("condition",), title="custom: error rate")
    assert found == {}


def test_mosaic_has_a_colour_bar_and_unit_labels_without_overlaps(tmp_path):
    steps = [{"POCi": np.eye(32), "PPCt": np.arange(13.0), "PMCm": np.eye(3)[s % 3], "PMCd": np.array([0.2, 0.1 * s])}
             for s in range(4)]
    with checking_overlaps() as found:
        fig_path = figures.map_panels(steps, tmp_path / "m.png", "recog/none: sample trials\nchosen: " + "a rule " * 40,
                                      [f"same 150deg, step {s + 1}" for s in range(4)],
                                      units={"PMCm": ["l", "s", "r"], "PMCd": ["YES", "NO"]})
    assert found == {} and fig_path.is_file()
    texts = set()
    orig = plt.Figure.savefig

    def keep(self, *a, **k):
        texts.update(t.get_text() for t in self.findobj(plt.Text))
        return orig(self, *a, **k)

    plt.Figure.savefig = keep
    try:
        figures.map_panels(steps, tmp_path / "m2.png", "t", units={"PMCm": ["l", "s", "r"], "PMCd": ["YES", "NO"]})
    finally:
        plt.Figure.savefig = orig
    assert {"l", "s", "r", "YES", "NO", "max", "min"} <= texts and any("scaled to its own range" in t for t in texts)


def _exp4(*overrides):
    """A quick Exp 4 run of two participants; its tests build 2 looks per item instead of 16 (what
    the figures, the report and TensorBoard show does not depend on it; building them is a fifth of
    the run)."""
    cfg = validate(make_cfg("experiment=exp4", "participants=2", "logger.sample_trials=2",
                            "experiment.quick.fm_images=2000", "experiment.percept.looks=2", *overrides))
    cfg.preset = "quick"
    return cfg


def _user_folder(path):
    from neuroimagery.vision.stimulus_sets import get_stimulus_set

    path.mkdir()
    s = get_stimulus_set("exp4-A")
    for o in s.objects[:3]:
        cv2.imwrite(str(path / f"{o}.png"), s.image(o, 0.0))
    return path


def test_a_user_folder_gets_a_report_of_its_own(tmp_path):
    folder = _user_folder(tmp_path / "shapes")
    with checking_overlaps() as found:
        s = evaluate(_exp4("logger=none", "stimuli=folder", f"stimuli.path={folder}"), out_dir=tmp_path / "run")
    assert found == {}, found
    report = (tmp_path / "run" / "report.md").read_text()
    assert "## Your stimuli" in report and f"`{folder}`" in report and "It replaces the Recog set" in report
    assert "Above chance? Mean correct rate" in report and "one-sided one-sample t-test" in report
    assert "sets A, B and C" not in report and "Gen1 and Gen2 rates" not in report
    for line in report.splitlines():  # no caption promises a thesis line the figure does not draw
        if line.startswith("*Figure ") and "(dashed" in line:
            assert "10 n" in line, line
    assert not (tmp_path / "run" / "figures" / "fig6_9c_correct.png").exists()
    custom = [e for e in s["effects"] if e["effect"].startswith("custom")]
    assert len(custom) >= 3 and all(e["n"] == 2 for e in custom)  # the effects that apply, on the user's shapes


def test_fresh_exp4_run_tensorboard_has_curves_and_every_rotation_step(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    with checking_overlaps() as found:
        evaluate(_exp4(), out_dir=tmp_path)
    assert found == {}, found  # fig6_10c_correct, fig6_11c_correct and the mosaics among them
    ea = EventAccumulator(str(tmp_path / "tb"), size_guidance={"images": 0, "scalars": 0, "tensors": 0})
    ea.Reload()
    scalars = ea.Tags()["scalars"]
    single = [t for t in scalars if not t.startswith("values/") and len(ea.Scalars(t)) < 2]
    assert not single and any(t.startswith("train/") for t in scalars), single
    assert {"summary/headline/text_summary", "summary/single_values/text_summary"} <= set(ea.Tags()["tensors"])
    trials = {t.rsplit("/", 1)[0] for t in ea.Tags()["images"]}
    assert trials and all(t.split("/")[0] in ("recog", "gen1", "gen2") for t in trials)
    df = pd.read_csv(tmp_path / "trials.csv")
    p0 = df[(df["participant"] == 0) & (df["rotations"] > 0) & df["decided"].astype(bool)]
    for trial in trials:
        test, cond, name = trial.split("/")
        steps = [e.step for e in ea.Images(f"{trial}/PMCm")]
        assert steps == list(range(1, len(steps) + 1)), (trial, steps)  # every step kept, none skipped
        if ((p0["test"] == test) & (p0["condition"] == cond)).any():  # participant 0 rotated in some trial
            assert len(steps) >= 2, trial  # so the one shown rotated: a still step, then moves
