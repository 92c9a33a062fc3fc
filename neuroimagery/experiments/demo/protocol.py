"""A small demonstration built from the blocks alone (no vision, no robot): mental rotation of
a population-coded angle.

Maps: ``ANGLE`` (orientation of the imagined object, 1-D, -90..90 deg) and ``POSTURE`` (wrist
posture, 1-D). Connection ``affordance`` (ANGLE -> POSTURE) and ``forward`` (POSTURE -> ANGLE)
learn by outstar Hebbian learning (eq. 4.2-4.3): the affordance maps an orientation to the
posture that would hold the object so; the forward model maps a posture to the orientation one
step (``step_deg``) closer to upright. Repeating affordance -> forward rotates the imagined angle
toward 0; the answer map is a dynamic field (two units, "same" / "different") whose input is the
overlap of the final imagined code with the upright target. RT = 10 cycles per rotation step +
field cycles. This is the same loop as Experiment 1 with images replaced by 1-D codes.
"""
from __future__ import annotations

import pandas as pd
import torch

from ...analysis.report import Report, reproducibility_note
from ...analysis.summary import TRIAL_COLUMNS, summarise_trials
from ...analysis.figures import rt_by_disparity
from ...core.checkpoints import load_checkpoint
from ...models.angle_rotation import AngleRotationModel
from ...nn import participant_generators


def train(cfg, run):
    model = AngleRotationModel(cfg.experiment, cfg.participants, cfg.seed)
    model.fit(cfg.seed)
    run.save_checkpoint("model", {"state_dict": model.state_dict(), "participants": cfg.participants})
    return model


def load(cfg, checkpoint_dir):
    state = load_checkpoint(checkpoint_dir, "model")
    model = AngleRotationModel(cfg.experiment, state["participants"], cfg.seed)
    model.load_state_dict(state["state_dict"])
    return model


def evaluate(cfg, run, model) -> dict:
    model.eval()
    P = model.participants
    angles = torch.arange(-90.0, 90.1, 5.0)
    gens = participant_generators(cfg.seed, P, stream=3)
    out = model.trial(angles.expand(P, -1).clone(), gens, run.logger, "sample")
    rows = []
    for p in range(P):
        for b, a in enumerate(angles.tolist()):
            rows.append({"participant": p, "test": "rotation", "condition": "none", "target_object": "angle",
                         "target_angle": 0.0, "target_appearance": "main", "rotated_object": "angle",
                         "rotated_angle": a, "rotated_appearance": "main", "disparity": abs(a), "same": True,
                         "answer": "yes" if bool(out["answer_same"][p, b]) else "no",
                         "correct": bool(out["answer_same"][p, b]), "rotation_steps": int(out["steps"][p, b]),
                         "rotated_ok": bool(out["rotated_ok"][p, b]), "rt": int(out["rt"][p, b])})
    df = pd.DataFrame(rows, columns=TRIAL_COLUMNS)
    run.write_csv("trials.csv", df)
    rt_by_disparity(df, run.figures / "rt_by_disparity.png", title="Demo: RT against disparity", ylabel="RT (cycles)")
    tests = summarise_trials(df)
    return {"experiment": "demo", "participants": P, "tests": tests, "targets": {}}


def report(cfg, run, summary) -> None:
    t = summary["tests"]["rotation/none"]
    r = Report("Demo: mental rotation of a population-coded angle")
    r.p("A demonstration of the building blocks (maps, Hebbian connections, a dynamic field); it has no "
        "counterpart in the thesis, so there are no targets.")
    r.table(["measure", "value"], [["participants", summary["participants"]], ["trials", t["n_trials"]],
                                   ["rotation success", f"{100 * t['rotation_success_rate']:.1f} %"],
                                   ["RT slope (cycles/deg)", t["rt_slope_per_deg"]], ["Pearson r (RT, disparity)", t["rt_r"]]])
    r.figure(run.figures / "rt_by_disparity.png", "Mean RT against disparity", root=run.root)
    r.p(reproducibility_note(cfg.seed) + f" Runtime: {summary['runtime_s']}.")
    r.write(run.report_path)
