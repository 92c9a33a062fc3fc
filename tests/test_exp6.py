"""Experiment 6: Shepard-Metzler objects, local forward models, batched == solo, label shuffling,
an end-to-end run on a tiny grid."""
import json

import numpy as np
import pytest
import torch
from conftest import make_cfg

from neuroimagery.config import validate
from neuroimagery.experiments import exp6
from neuroimagery.models import voxels
from neuroimagery.models.rotation_3d import MOVES, Rotation3D, fm_bytes, grid_for_budget
from neuroimagery.nn import Delta, seeding
from neuroimagery.nn.local import LocalConnection
from neuroimagery.run import evaluate
from neuroimagery.vision import shepard_metzler as sm

TINY = ("experiment.grid=10", "experiment.quick_fm_images=3000", "experiment.posture_iterations=100",
        "experiment.quick_objects=1", "experiment.train_objects=1", "experiment.test_angles=[0,60,120,180]",
        "experiment.posture_angles=[0,60,120,180]", "experiment.step_deg=30")


def _cfg(*overrides, quick=True):
    cfg = validate(make_cfg("experiment=exp6", "logger=none", *overrides))
    cfg.preset = "quick" if quick else "full"
    return cfg


def test_generated_objects_are_chiral_and_mirrors_differ_from_every_rotation():
    objs = sm.generate(8, seed=0)
    assert len({sm.canonical(o) for o in objs}) == 8
    for o in objs:
        assert len(o) == 10 and sm.is_chiral(o)
        assert len({tuple(r) for r in o.tolist()}) == 10  # no cube repeats
        steps = np.abs(np.diff(o, axis=0)).sum(1)
        assert (steps == 1).all()  # a path of face-joined cubes
        turns = (np.abs(np.diff(np.diff(o, axis=0), axis=0)).sum(1) > 0).sum()
        assert turns == 3  # four arms, three elbows
        m = sm.mirror(o)
        lattice = np.round(m - m.min(0)).astype(int)
        assert np.allclose(m - m.min(0), lattice)  # a lattice reflection: the cubes stay face to face
        rots = {sm.canonical(o @ r.T) for r in sm._cube_group()}
        assert len(sm._cube_group()) == 24
        assert sm.canonical(lattice) not in rots  # the mirror is none of the 24 rotations
        # nor any rotation in between: the best of many random rotations leaves a cube centre > 0.4 cube away
        g = np.random.default_rng(0)
        c = sm.centred(o)
        best = np.inf
        for _ in range(400):
            q = np.linalg.qr(g.normal(size=(3, 3)))[0]
            q = q * np.sign(np.linalg.det(q))
            d = np.linalg.norm((c @ q.T)[:, None] - m[None], axis=-1).min(1).max()
            best = min(best, d)
        for r in sm._cube_group():
            best = min(best, np.linalg.norm((c @ r.T)[:, None] - m[None], axis=-1).min(1).max())
        assert best > 0.4


def test_check_object_refuses_flat_and_broken_objects():
    with pytest.raises(ValueError, match="own mirror"):
        sm.check_object([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0]])  # a flat L is achiral in 3-D
    with pytest.raises(ValueError, match="face to face"):
        sm.check_object([[0, 0, 0], [1, 0, 0], [3, 0, 0], [3, 1, 0]])
    with pytest.raises(ValueError, match="test_cubes"):
        exp6.Exp6Config(test_cubes=[[[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 1, 0]]])
    with pytest.raises(ValueError, match="hidden"):
        exp6.Exp6Config(hidden="all")
    with pytest.raises(ValueError, match="unreachable"):
        exp6.Exp6Config(unreachable="wrap")


def test_grid_rule_fits_the_memory_budget():
    g = grid_for_budget(24.0, 20.0)
    assert g == 18 and fm_bytes(g, 20.0) <= 24e6 < fm_bytes(g + 2, 20.0)
    assert exp6.grid_side(exp6.Exp6Config()) == g
    # ten participants' forward models stay far below the 8 GB the protocol may use; a dense 24^3
    # forward model would need about 0.76 GB on its own
    assert 10 * fm_bytes(g, 20.0) < 0.3e9 and (24 ** 3) ** 2 * 4 > 0.75e9


def test_local_connection_index_form_equals_dense_delta_rule():
    """The index form of the delta rule gives the dense form's weights; both equal the all-to-all rule
    restricted to the receptive fields."""
    side, P = 8, 2
    a = LocalConnection(side, 2, seeding.participant_generators(0, P), rules=Delta(0.1))
    b = LocalConnection(side, 2, seeding.participant_generators(0, P), rules=Delta(0.1))
    w0 = torch.stack([a.dense(p) for p in range(P)])
    wi = voxels.warp_index(side, "y", 30)
    tg = voxels.warp_targets(wi)
    g = torch.Generator().manual_seed(5)
    idx = torch.stack([voxels.dot_indices(24, side, g) for _ in range(P)])
    idx[0, 0, 1] = idx[0, 0, 0]  # a repeated dot counts once
    X = torch.zeros(P, 24, side ** 3).scatter_(2, idx, 1.0)
    Y = voxels.warp(X, wi)
    T = tg[idx].reshape(P, 24, -1)
    ref = w0.clone()
    for s in range(0, 24, 8):
        x, y = X[:, s:s + 8], Y[:, s:s + 8]
        ref = ref + 0.1 * torch.bmm((y - torch.bmm(x, ref.transpose(1, 2))).transpose(1, 2), x) * (w0 != 0)
        a.learn(pre=x, target=y)
        b.learn(pre_index=idx[:, s:s + 8], target_index=T[:, s:s + 8])
    wa = torch.stack([a.dense(p) for p in range(P)])
    assert not torch.allclose(wa, w0)
    assert torch.allclose(wa, torch.stack([b.dense(p) for p in range(P)]), atol=1e-6)
    assert torch.allclose(wa, ref, atol=1e-5)


def test_forward_model_rotates_a_held_out_dot_cloud_one_step():
    """Trained on random 3-D dots, every forward model turns held-out dots (another stream) by one
    step with IoU >= 0.8 against the exact warp (the stated overlap), on a 10^3 grid."""
    e = exp6.Exp6Config(grid=10)
    model = Rotation3D(e, 10, seeding.participant_generators(0, [0]))
    model.train()
    exp6.dot_training(model, seeding.participant_generators(0, [0], 1), 9000, 32)
    x = voxels.dot_images(300, 10, torch.Generator().manual_seed(99))
    part = torch.zeros(300, dtype=torch.long)
    for m, (ax, deg) in enumerate(model.moves):
        truth = voxels.warp(x, voxels.warp_index(10, ax, deg))
        iou = float(voxels.overlap_iou(model.predict(x, torch.full((300,), m), part), truth).mean())
        assert iou >= 0.8, (MOVES[m], iou)


def test_views_are_3d_maps_and_the_mirror_looks_different():
    e = exp6.Exp6Config()
    with exp6.make_scene(e) as scene:
        cells = sm.generate(1)[0]
        a = exp6.see(scene, e, 18, 1.8, cells, "basic", "depth", 0)
        b = exp6.see(scene, e, 18, 1.8, cells, "mirror", "depth", 0)
        c = exp6.see(scene, e, 18, 1.8, cells, "basic", "picture", 0)
    assert torch.equal(a, c) and 40 < a.sum() < 600
    z = a.reshape(18, 18, 18).nonzero()[:, 0]
    assert z.max() - z.min() >= 3  # the map has depth, not one plane
    assert voxels.overlap_iou(a, b) < 0.8


def test_batched_participants_equal_solo_runs():
    cfg = _cfg("participants=2", *TINY)
    both = exp6.train_model(cfg, [0, 1])
    solo = exp6.train_model(cfg, [1])
    assert torch.allclose(both.fm[2].weight[1], solo.fm[2].weight[0], atol=1e-6)
    assert torch.allclose(both.c16[1].weight[1], solo.c16[1].weight[0], atol=1e-5)
    db, _, _ = exp6.run_tests(cfg, both)
    ds, _, _ = exp6.run_tests(cfg, solo)
    b1 = db[db["participant"] == 1].reset_index(drop=True)
    assert len(b1) == len(ds) > 0
    for k in ("answer", "rt", "rotation_steps", "decided"):
        assert (b1[k].to_numpy() == ds[k].to_numpy()).all(), k


def test_answers_do_not_read_labels(monkeypatch):
    """Shuffling every label column of the trial table, images kept, changes no answer or RT."""
    from support_labels import assert_run_tests_read_no_labels

    cfg = _cfg("participants=2", *TINY)
    model = exp6.train_model(cfg, [0, 1])
    assert_run_tests_read_no_labels(monkeypatch, exp6, cfg, model, tables=exp6, moved="rotated_angle")


def test_end_to_end_quick_run_writes_results(tmp_path):
    cfg = validate(make_cfg("experiment=exp6", "participants=1", "logger.sample_trials=1", *TINY))
    cfg.preset = "quick"
    evaluate(cfg, out_dir=tmp_path)
    for f in ("trials.csv", "summary.json", "report.md", "checkpoints/exp6.pt", "figures/exp6_fig2_rt.png",
              "figures/exp6_stimuli.png", "figures/exp6_maps_picture.png"):
        assert (tmp_path / f).exists(), f
    assert any((tmp_path / "tb").iterdir())
    s = json.loads((tmp_path / "summary.json").read_text())
    assert set(s["tests"]) == {"picture/none", "depth/none"}
    for v in s["tests"].values():
        assert {"rt_slope_per_deg", "rt_intercept", "rt_r", "correct_rate", "same_pairs"} <= set(v)
        assert v["n_trials"] == 4 * 2  # one object, four angles, same and mirror
    assert set(s["headline"]["goals"]) and "Shepard" in (tmp_path / "report.md").read_text()


def test_wrist_signal_joins_the_line_of_sight_posture_map_only():
    cfg = _cfg("participants=1", *TINY)
    model = exp6.train_model(cfg, [0])
    units = torch.tensor([[0, 1, 1], [2, 3, 0]])  # (rows, axes x y z)
    still = model.ppc_code(units)
    z = 2  # WRIST_AXIS
    for cond, j in (("match", units[:, z]), ("mismatch", 3 - units[:, z])):
        code = model.ppc_code(units, cond)
        assert torch.equal(code[:, :z], still[:, :z])  # the other axes' maps are untouched
        want = (still[:, z] + cfg.experiment.proprio_gain * model.ppc.encode(j.float())).clamp(0, 1)
        assert torch.allclose(code[:, z], want)
    assert not torch.equal(model.ppc_code(units, "mismatch"), still)
    with pytest.raises(ValueError, match="proprioception"):
        model.ppc_code(units, "other")


def test_wrist_conditions_leave_the_still_condition_unchanged():
    cfg = _cfg("participants=1", *TINY)
    model = exp6.train_model(cfg, [0])
    alone, _, _ = exp6.run_tests(cfg, model)
    cfg.experiment.conditions = ["none", "match", "mismatch"]
    every, _, _ = exp6.run_tests(cfg, model)
    assert set(every["condition"]) == {"none", "match", "mismatch"} and len(every) == 3 * len(alone)
    none = every[every["condition"] == "none"].reset_index(drop=True)
    for k in ("answer", "rt", "rotation_steps", "decided"):
        assert (none[k].to_numpy() == alone[k].to_numpy()).all(), k
    from neuroimagery.experiments import exp6_report

    names = [r["effect"] for r in exp6_report.effects(every)]
    assert any("match minus none" in n for n in names) and any("mismatch minus none" in n for n in names)


BAD = [
    (["experiment.conditions=[match]"], "experiment.conditions"),
    (["experiment.conditions=[none,none]"], "experiment.conditions"),
    (["experiment.test_cubes=[[[0,0,0],[1,0,0],[2,0,0],[2,1,0]]]"], "experiment.test_cubes[0]"),
    (["experiment.hidden=all"], "experiment.hidden"),
    (["experiment.fm_memory_mb=nan"], "experiment.fm_memory_mb"),
    (["experiment.grid=9"], "experiment.grid"),
    (["preset=quick", "experiment.fm_images=100"], "experiment.fm_images"),
    (["experiment.grid=12", "experiment.fm_memory_mb=5"], "experiment.fm_memory_mb"),
]


@pytest.mark.parametrize("over,needle", BAD, ids=[" ".join(o) for o, _ in BAD])
def test_bad_settings_are_refused_before_any_work(tmp_path, capsys, monkeypatch, over, needle):
    from neuroimagery import cli

    def forbidden(*a, **k):
        raise AssertionError("training started before the input was refused")

    monkeypatch.setattr(exp6, "train", forbidden)
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(evaluate)(make_cfg("experiment=exp6", *over), out_dir=tmp_path)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert ex.value.code == 2 and len(lines) == 1 and needle in lines[0], err
