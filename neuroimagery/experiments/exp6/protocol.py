"""Experiment 6 (beyond the thesis): mental rotation of Shepard-Metzler objects in three
dimensions, seen by the iCub's eye. Model: :class:`neuroimagery.models.rotation_3d.Rotation3D`
(search, transform, confirm).

Protocol (docs/exp6.md): the completion map learns from random cube chains in random poses, the
forward models from graded dot images turned by each move, and the confirm stage's cut is fixed on
the training objects' pairs; tests ``picture`` (rotation about the line of sight) and ``depth``
(about the vertical), 0-180 deg in 20-deg steps, same or mirror pairs of the test objects, and
optionally ``oblique`` (about an oblique axis, off-grid angles). RT = accumulator cycles.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import torch

from ...core import progress
from ...nn import monitor, seeding
from ...vision import shepard_metzler as sm
from . import data as data
from .config import CONDITIONS, TESTS  # noqa: F401  (the schema)
from .data import cube_voxels, grid_side, make_scene, objects, pair_bank, see  # noqa: F401


# ------------------------------------------------------------------------------ training
def _model(cfg, ids):
    from ...models.rotation_3d import Rotation3D

    e = cfg.experiment
    side = grid_side(e)
    return Rotation3D(e, side, seeding.participant_generators(cfg.seed, ids, stream=0), cube_voxels(e, side))


def train_completion(model, cfg, ids, scene) -> None:
    """C_fill: random chains in random poses (never a built-in object), seen by the eye once per run;
    each participant learns from them in its own order."""
    e = cfg.experiment
    n = e.quick.chains if cfg.preset == "quick" else e.image.chains
    s, w, _, _ = data.chain_views(scene, e, model.side, model.cube_voxels, n, cfg.seed, 1000)
    code_s, code_w = model.encode(s), model.encode(w)
    order = torch.stack([torch.randperm(n, generator=g) for g in seeding.participant_generators(cfg.seed, ids, stream=9)])
    model.fit_completion(code_s[order], code_w[order], e.image.batch)


CURVE_POINTS = 10  # points of each forward model's training curve (each costs one product of the batch)


def train_forward_models(model, cfg, ids) -> None:
    """Each forward model: graded dot images at sub-voxel positions and the same dots turned by its move.
    The moves are independent (a connection and generators of their own each), so with a thread
    budget of several threads (:func:`~neuroimagery.nn.functional.thread_budget`) they learn side
    by side, each in its own order; the weights are those of one move after the other."""
    from concurrent.futures import ThreadPoolExecutor

    from ...models import voxel_code as vc
    from ...nn.functional import thread_budget

    e = cfg.experiment
    n = e.quick.fm_images if cfg.preset == "quick" else e.fm.images

    starts = range(0, n, e.fm.batch)
    every = max(1, len(starts) // CURVE_POINTS)
    points: dict[int, list] = {}  # move -> (images seen, squared error of the batch before its change)

    def learn(m: int) -> None:
        axis, deg = model.moves[m]
        R = vc.axis_rotation(axis, deg)
        gens = seeding.participant_generators(cfg.seed, ids, stream=10 + m)
        points[m] = []
        for b, s in enumerate(starts):
            x, y = data.dot_pair(gens, min(e.fm.batch, n - s), e.fm.dots, model.side, e.image.sigma, R)
            if watch and (b % every == 0 or b == len(starts) - 1):
                points[m].append((s + x.shape[1], float(model.forward_error(m, x, y))))
            model.fit_forward_models(m, x, y)

    watch = monitor.active()
    moves = range(1, len(model.moves))
    workers = min(thread_budget(), len(moves))
    bar = progress.bar(total=len(moves), what="forward models", unit="move")
    if workers <= 1:
        for m in moves:
            learn(m)
            bar.update(1)
    else:
        with ThreadPoolExecutor(workers) as pool:
            for _ in pool.map(learn, moves):
                bar.update(1)
    bar.close()
    for m in moves if watch else ():  # recorded here, in this thread, in the moves' order
        for step, value in points[m]:
            monitor.record(model.forward_curve(m), value, step)


def angles(e, kind: str) -> list[float]:
    return list(e.oblique_angles) if kind == "oblique" else list(e.test_angles)


def fit_confirm(model, cfg, ids, scene) -> None:
    """The cut between same and mirror pairs, fixed on the training objects' pairs (picture and depth,
    the test angles) after the model's own search and transform."""
    e = cfg.experiment
    train, tnames, _, _ = objects(e)
    images, index = pair_bank(model, cfg, scene, train, tnames, sm.KINDS, ids, lambda k: e.test_angles)
    tgt, rot, same = [], [], []
    for name in tnames:
        for kind in sm.KINDS:
            for ang in e.test_angles:
                for app in ("basic", "mirror"):
                    tgt.append(index[(name, None, 0.0, "basic")])
                    rot.append(index[(name, kind, float(ang), app)])
                    same.append(app == "basic")
    gens = seeding.participant_generators(cfg.seed, ids, stream=50)
    out = model.align(images[:, tgt], images[:, rot], gens)
    match, cubes = model.mismatch(out["turned"], out["target"])
    P = len(ids)
    model.fit_confirm(cubes.reshape(P, -1), match.reshape(P, -1), torch.tensor(same))


def train_model(cfg, ids, scene=None):
    """Train participants ``ids`` (a batched run equals their solo runs)."""
    from ...nn.functional import intra_op_threads

    e = cfg.experiment
    model = _model(cfg, ids)
    model.train()
    own = scene is None
    scene = make_scene(e) if own else scene
    try:
        with intra_op_threads(e.train_threads, cap=True):
            train_completion(model, cfg, ids, scene)
            train_forward_models(model, cfg, ids)
            model.eval()
            fit_confirm(model, cfg, ids, scene)
    finally:
        if own:
            scene.close()
    model.participant_ids = list(ids)
    return model


def train(cfg, run):
    ids = list(range(cfg.participants))
    model = train_model(cfg, ids)
    run.save_checkpoint("exp6", {"state_dict": model.state_dict(), "participants": list(ids)})
    return model


def load(cfg, checkpoint_dir):
    from ...core.checkpoints import load_checkpoint

    ck = load_checkpoint(checkpoint_dir, "exp6")
    model = _model(cfg, ck["participants"])
    model.load_state_dict(ck["state_dict"])
    model.eval()
    model.participant_ids = list(ck["participants"])
    return model


# ------------------------------------------------------------------------------ tests
def trial_table(index, names, e, test: str, condition: str = "none") -> pd.DataFrame:
    """One row per pair of a test: the target in the general view, the comparison turned by each angle."""
    rows = []
    for name in names:
        for app in ("basic", "mirror"):
            for ang in angles(e, test):
                rows.append({"test": test, "condition": condition, "target_object": name, "target_angle": 0.0,
                             "target_appearance": "basic", "rotated_object": name, "rotated_angle": float(ang),
                             "rotated_appearance": app, "same": app == "basic",
                             "target_row": index[(name, None, 0.0, "basic")], "rotated_row": index[(name, test, float(ang), app)]})
    df = pd.DataFrame(rows)
    df["disparity"] = df["rotated_angle"].round().astype(int)
    return df


def rotated_ok(kind: str, angle: np.ndarray, turned: np.ndarray, step: float) -> np.ndarray:
    """The net mental rotation (per camera axis) undid the stimulus's within half a step on every axis."""
    from ...models.rotation_3d import AXES

    want = np.zeros_like(turned)
    if kind == "oblique":
        want[:] = -angle[:, None] * sm.OBLIQUE_AXIS[None, :]
    else:
        want[:, AXES.index(sm.KIND_AXIS[kind])] = -angle
    d = (turned - want + 180.0) % 360.0 - 180.0
    return (np.abs(d) <= step / 2 + 1e-6).all(1)


def test_names(cfg):
    e = cfg.experiment
    _, _, test, names = objects(e)
    if cfg.preset == "quick" and e.objects.test_cubes is None:
        test, names = test[:e.quick.objects], names[:e.quick.objects]
    return test, names


def sample_trials(table: pd.DataFrame, count: int) -> list[int]:
    """The ``count`` trials of participant 0 recorded step by step (the report's and TensorBoard's
    sample trials): the first object's pairs at the largest angle, the same pair first, then the
    mirror pair, then the next angle down, so that a sample trial shows a long mental rotation.
    Only what is recorded depends on the choice, not any answer."""
    first = table[table["target_object"] == table["target_object"].iloc[0]]
    order = first.assign(mirror=~first["same"].astype(bool)).sort_values(["rotated_angle", "mirror"],
                                                                         ascending=[False, True], kind="stable")
    return [int(i) for i in order.index[:max(0, int(count))]]


def run_tests(cfg, model, scene=None, record: int = 0):
    """Every test -> (trials DataFrame, sample histories, bank images)."""
    from ...analysis.summary import TRIAL_COLUMNS

    e = cfg.experiment
    ids = getattr(model, "participant_ids", list(range(model.participants)))[:model.participants]
    test, names = test_names(cfg)
    own = scene is None
    scene = make_scene(e) if own else scene
    try:
        images, index = pair_bank(model, cfg, scene, test, names, e.tests, ids, lambda k: angles(e, k))
    finally:
        if own:
            scene.close()
    frames, histories = [], {}
    tables = {(t, cond): trial_table(index, names, e, t, cond) for t in e.tests for cond in e.conditions}
    progress.expect(sum(len(tb) for tb in tables.values()) * len(ids))
    for k, t in enumerate(e.tests):
        for cond in e.conditions:
            table = tables[t, cond]
            tgt = images[:, torch.as_tensor(table["target_row"].to_numpy().copy())]
            rot = images[:, torch.as_tensor(table["rotated_row"].to_numpy().copy())]
            stream = 100 + TESTS.index(t) + 10 * CONDITIONS.index(cond)  # none keeps the stream of a run without the others
            shown = sample_trials(table, record)
            out = model.run(tgt, rot, seeding.participant_generators(cfg.seed, ids, stream=stream), record=shown,
                            proprioception=cond)
            histories[f"{t}/{cond}"] = {"steps": out.pop("history"), "trials": [
                {k: table.iloc[i][k] for k in ("target_object", "rotated_angle", "same")} for i in shown]}
            for j, pid in enumerate(ids):
                df = table.drop(columns=["target_row", "rotated_row"]).copy()
                df.insert(0, "participant", int(pid))
                df["answer"] = np.where(out["answer"][j].numpy() == 0, "yes", "no")
                df["correct"] = (df["answer"] == "yes") == df["same"].astype(bool)
                df["rotation_steps"] = out["rotation_steps"][j].numpy().astype(int)
                df["rotated_ok"] = rotated_ok(t, df["rotated_angle"].to_numpy(), out["turned"][j].numpy(), e.step_deg)
                df["rt"] = out["rt"][j].numpy()
                df["decided"] = out["decided"][j].numpy()
                df["match"] = out["match"][j].numpy().round(4)
                df["mismatch_cubes"] = out["cubes"][j].numpy().round(3)
                frames.append(df[TRIAL_COLUMNS + ["decided", "match", "mismatch_cubes"]])
            progress.advance(len(table) * len(ids), note=f"{t}/{cond}")
    return pd.concat(frames, ignore_index=True), histories, images


def effects(df: pd.DataFrame) -> list[dict]:
    """Shepard & Metzler's effects and, with wrist conditions, the proprioception effects
    (``exp6_report.effects``), the participant as the unit; also used when runs are pooled."""
    from . import report as exp6_report

    return exp6_report.effects(df)


def evaluate(cfg, run, trained) -> dict:
    """The tests (``trials.csv``), the stimuli's contact sheet and the stage measures (``exp6_stages``),
    summarised, drawn and logged by ``exp6_report.summarise``."""
    from . import report as exp6_report, stages as exp6_stages

    e = cfg.experiment
    scene = make_scene(e)
    try:
        df, histories, _ = run_tests(cfg, trained, scene, record=cfg.logger.sample_trials)
        train_objs, tnames, test_objs, names = objects(e)
        used = sorted(set(df["target_object"]), key=names.index)  # the test objects of this run (preset)
        extra = [u for u in used if u not in tnames]
        sm.contact_sheet(scene, list(train_objs) + [test_objs[names.index(u)] for u in extra], list(tnames) + extra,
                         run.figures / "exp6_stimuli.png", tilt_deg=e.view.tilt_deg, turn_deg=e.view.turn_deg)
    finally:
        scene.close()
    run.write_csv("trials.csv", df)
    scene = make_scene(e)
    try:
        stages = exp6_stages.measure(trained, cfg, scene)
    finally:
        scene.close()
    return exp6_report.summarise(run, trained, df, histories, stages)


def report(cfg, run, summary) -> None:
    from . import report as exp6_report

    exp6_report.report(cfg, run, summary)
