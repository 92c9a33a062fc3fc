"""Experiment 6: Shepard-Metzler objects, local connections (sparse graded path), Sanger's rule,
batched == solo, label shuffling, the wrist signal, an end-to-end run on a tiny grid."""
import json

import numpy as np
import pytest
import torch
from conftest import make_cfg
from support_experiments import patch_experiment
from support_bad_inputs import hydra_reporter  # noqa: F401 (fixture)

from neuroimagery.config import validate
from neuroimagery.experiments.exp6 import protocol as exp6
from neuroimagery.experiments.exp6.config import Exp6Config, ObjectParams
from neuroimagery.models import voxels
from neuroimagery.models import voxel_code as vc
from neuroimagery.models.rotation_3d import Rotation3D, fm_bytes, grid_for_budget
from neuroimagery.nn import Connection, Delta, Sanger, seeding
from neuroimagery.nn.local import LocalConnection
from neuroimagery.app.run import evaluate
from neuroimagery.vision import shepard_metzler as sm

TINY = ("experiment.grid=10", "experiment.quick.fm_images=16", "experiment.quick.chains=8",
        "experiment.quick.objects=1", "experiment.objects.train=1", "experiment.test_angles=[0,60,120,180]",
        "experiment.step_deg=30", "experiment.search.iterations=20")


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


def _margin_by_hand(cells) -> int:
    """The mirror margin counted one rotation and one shift at a time (no vectorising)."""
    c = np.asarray(cells, int)
    own = {tuple(x) for x in c.tolist()}
    best = 0
    for r in sm._cube_group():
        m = (c * np.array([-1, 1, 1])) @ r.T
        for a in c:
            for b in m:
                best = max(best, sum(tuple(x) in own for x in (m + (a - b)).tolist()))
    return len(c) - best


def test_mirror_margin_counts_the_cubes_a_mirror_leaves_uncovered():
    assert sm.mirror_margin([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0]]) == 0  # a flat L is its own mirror
    chiral = sm.generate(8, seed=0, min_margin=1)
    assert [sm.mirror_margin(o) for o in chiral] == [_margin_by_hand(o) for o in chiral]
    assert min(sm.mirror_margin(o) for o in chiral) == 1  # chirality alone admits one-cube mirrors
    kept = sm.generate(8, seed=0, min_margin=2)
    assert all(sm.mirror_margin(o) >= 2 for o in kept)
    chains = sm.random_chains(30, np.random.default_rng(3), exclude=kept, min_margin=2)
    assert all(_margin_by_hand(c) >= 2 for c in chains)
    one = next(o for o in chiral if sm.mirror_margin(o) == 1).tolist()
    with pytest.raises(ValueError, match="mirror_cubes"):
        ObjectParams(test_cubes=[one])
    ObjectParams(test_cubes=[one], mirror_cubes=1)  # chirality alone


def test_check_object_refuses_flat_and_broken_objects():
    with pytest.raises(ValueError, match="own mirror"):
        sm.check_object([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0]])  # a flat L is achiral in 3-D
    with pytest.raises(ValueError, match="face to face"):
        sm.check_object([[0, 0, 0], [1, 0, 0], [3, 0, 0], [3, 1, 0]])
    with pytest.raises(ValueError, match="experiment.objects.test_cubes"):
        ObjectParams(test_cubes=[[[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 1, 0]]])
    with pytest.raises(ValueError, match="strategy"):
        Exp6Config(strategy="guess")


def test_grid_rule_fits_the_memory_budget():
    g = grid_for_budget(20.0, 20.0)
    assert g == 18 and fm_bytes(g, 20.0) <= 20e6 < fm_bytes(g + 2, 20.0)
    assert exp6.grid_side(Exp6Config()) == g
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


def test_sparse_graded_path_equals_the_dense_path():
    """Graded inputs with few active units take the sparse path of a local connection: its product
    and its delta-rule change equal the dense path's."""
    side, P = 8, 2
    a = LocalConnection(side, 2, seeding.participant_generators(0, P), rules=Delta(0.05))
    b = LocalConnection(side, 2, seeding.participant_generators(0, P), rules=Delta(0.05))
    g = torch.Generator().manual_seed(3)
    pts = (torch.rand(P * 4, 2, 3, generator=g) - 0.5) * 4
    x = vc.blobs(pts, side, 0.7).reshape(P, 4, -1)
    assert 0 < float((x != 0).float().mean()) <= 0.25 and ((x > 0) & (x < 1)).any()
    y = vc.blobs(pts + 0.5, side, 0.7).reshape(P, 4, -1)
    part = torch.arange(P).repeat_interleave(4)
    dense = a.net(x).reshape(P * 4, -1)
    assert torch.allclose(a.net_rows(x.reshape(P * 4, -1), part), dense, atol=1e-5)
    a.learn(pre=x, target=y)  # sparse path
    W0 = b.weight.clone()
    err = y - b.net(x)
    pad = torch.cat([x, x.new_zeros(P, 4, 1)], -1)
    want = W0 + 0.05 * torch.stack([(err * pad[..., b.source[:, k]]).sum(1) for k in range(b.K)], -1) * (b.source < side ** 3)
    assert torch.allclose(a.weight, want, atol=1e-5) and not torch.allclose(a.weight, W0)


def test_sanger_rule_learns_the_principal_axes_in_order():
    g = torch.Generator().manual_seed(0)
    Q = vc.random_rotations(1, g)[0]
    X = (torch.randn(1, 400, 3, generator=g, dtype=torch.float64) * torch.tensor([3.0, 2.0, 0.7], dtype=torch.float64)) @ Q.T
    conn = Connection(3, 3, torch.linalg.qr(torch.randn(1, 3, 3, generator=g, dtype=torch.float64))[0], rules=Sanger(0.5))
    conn.train()
    for _ in range(300):
        conn.learn(X)
    W = conn.weight[0] / conn.weight[0].norm(dim=-1, keepdim=True)
    _, vec = torch.linalg.eigh(X[0].T @ X[0])  # the sample's principal axes, by increasing spread
    assert torch.allclose((W @ vec.flip(-1)).abs(), torch.eye(3, dtype=torch.float64), atol=0.02)


def test_search_finds_an_exact_turn_of_whole_objects():
    """The search on whole objects turned exactly: the estimate lies within half a step of the
    turn, and it is proper."""
    cfg = _cfg()
    e = cfg.experiment
    model = Rotation3D(e, 18, seeding.participant_generators(0, [0], stream=0), 1.8)
    t = (torch.arange(3, dtype=torch.float64) - 1.0) / 3.0
    sub = torch.stack(torch.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    cells = torch.from_numpy(sm.centred(sm.generate(2)[1])).double()
    pts = ((cells.unsqueeze(1) + sub.unsqueeze(0)).reshape(-1, 3) * 1.8)
    turns = [vc.axis_rotation("y", 100.0), vc.axis_rotation("y", -160.0), vc.axis_rotation("z", 140.0),
             vc.random_rotations(1, torch.Generator().manual_seed(3))[0]]
    R = torch.stack(turns)
    target = vc.blobs(pts.expand(len(turns), -1, -1).float(), 18, e.image.sigma)
    comp = vc.blobs((pts @ R).float(), 18, e.image.sigma)  # each comparison is the target turned by R^T
    est, proper = model.search(target, comp, torch.zeros(len(turns), dtype=torch.long))
    err = vc.axis_angle(est @ R.transpose(1, 2))[1]
    assert proper.all() and (err <= e.step_deg / 2).all(), err


def test_views_are_3d_maps_and_the_mirror_looks_different():
    e = Exp6Config()
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
    assert torch.allclose(both.cut[1], solo.cut[0])
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


def test_sample_trials_show_every_step_of_a_rotation(tmp_path, monkeypatch):
    """The sample trials are the first object's pairs at the largest angle; the figure and
    TensorBoard show every step of the recorded trial, as many as the trial made (trials.csv)."""
    import pandas as pd
    from support_figures import checking_overlaps
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from neuroimagery.analysis import figures

    drawn = {}
    real = figures.map_panels

    def spy(steps, path, title="", row_labels=None, units=None):
        drawn[str(path).rsplit("/", 1)[-1]] = (len(steps), list(row_labels), title)
        return real(steps, path, title=title, row_labels=row_labels, units=units)

    monkeypatch.setattr(figures, "map_panels", spy)
    cfg = validate(make_cfg("experiment=exp6", "participants=1", "logger.sample_trials=2", *TINY))
    cfg.preset = "quick"
    with checking_overlaps() as found:
        evaluate(cfg, out_dir=tmp_path)
    assert not {k: v for k, v in found.items() if k.startswith("exp6_maps")}  # nothing clipped or overlapping
    df = pd.read_csv(tmp_path / "trials.csv")
    ea = EventAccumulator(str(tmp_path / "tb"), size_guidance={"images": 0, "scalars": 0}).Reload()
    for test in ("picture", "depth"):
        d = df[(df["test"] == test) & (df["participant"] == 0)]
        shown = d[(d["rotated_angle"] == d["rotated_angle"].max()) & d["same"]].iloc[0]
        steps = min(int(shown["rotation_steps"]) + 1, cfg.experiment.selection.max_steps)
        assert steps >= 3, "the sample trial shows a rotation"
        n, labels, title = drawn[f"exp6_maps_{test}.png"]
        assert n == len(labels) == steps and labels[-1].endswith("still") and "180 deg" in title
        for k in (0, 1):  # both sample trials, every step, in TensorBoard
            events = ea.Images(f"{test}/none/trial{k}/POCp_front")
            assert [e.step for e in events] == list(range(1, len(events) + 1))
        assert len(ea.Images(f"{test}/none/trial0/POCp_front")) == steps
    curves = [t for t in ea.Tags()["scalars"] if t.startswith("train/") and len(ea.Scalars(t)) > 1]
    assert len(curves) == 6, curves  # each forward model's training curve
    from tensorboard.plugins.hparams import plugin_data_pb2
    info = plugin_data_pb2.HParamsPluginData.FromString(
        ea.PluginTagToContent("hparams")["_hparams_/session_start_info"]).session_start_info
    assert info.hparams["experiment.fm.images"].number_value == 16  # as the quick run used it
    report = (tmp_path / "report.md").read_text()
    assert "{" not in report.split("## All tests")[0]  # no Python dict in a table cell
    assert "*exp6 maps picture*" not in report and "every step" in report


def test_wrist_signal_joins_the_line_of_sight_rotation_code_only():
    cfg = _cfg("participants=1", *TINY)
    model = exp6.train_model(cfg, [0])
    done = torch.tensor([[0.0, 30.0, 60.0], [30.0, 0.0, -90.0]])
    still = model.ppc_code(done)
    z = 2  # WRIST_AXIS
    for cond, w in (("match", done[:, z]), ("mismatch", -done[:, z])):
        code = model.ppc_code(done, cond, done[:, z])
        assert torch.equal(code[:, :z], still[:, :z])  # the other axes' codes are untouched
        want = (still[:, z] + cfg.experiment.ppc.proprio_gain * model.ppc.encode(w.unsqueeze(-1)).reshape(2, -1)).clamp(0, 1)
        assert torch.allclose(code[:, z], want)
    assert not torch.equal(model.ppc_code(done, "mismatch", done[:, z]), still)
    with pytest.raises(ValueError, match="proprioception"):
        model.ppc_code(done, "other")


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
    from neuroimagery.experiments.exp6 import report as exp6_report

    names = [r["effect"] for r in exp6_report.effects(every)]
    assert any("match minus none" in n for n in names) and any("mismatch minus none" in n for n in names)


BAD = [
    (["experiment.conditions=[match]"], "experiment.conditions"),
    (["experiment.conditions=[none,none]"], "experiment.conditions"),
    (["experiment.objects.test_cubes=[[[0,0,0],[1,0,0],[2,0,0],[2,1,0]]]"], "experiment.objects.test_cubes[0]"),
    (["experiment.fm.memory_mb=nan"], "experiment.fm.memory_mb"),
    (["experiment.grid=9"], "experiment.grid"),
    (["preset=quick", "experiment.fm.images=100"], "experiment.fm.images"),
    (["experiment.grid=12", "experiment.fm.memory_mb=5"], "experiment.fm.memory_mb"),
    (["experiment.strategy=guess"], "experiment.strategy"),
    (["experiment.search.iterations=0"], "experiment.search.iterations"),
    (["experiment.objects.test_set=other"], "experiment.objects.test_set"),
    (["experiment.view.eye=middle"], "experiment.view.eye"),
    (["experiment.view.image_width=10"], "experiment.view.image_width"),
    (["experiment.image.sigma=-1"], "experiment.image.sigma"),
    (["experiment.image.fill_depth=-2"], "experiment.image.fill_depth"),
    (["experiment.fm.dots=0"], "experiment.fm.dots"),
    (["experiment.confirm.level=1.5"], "experiment.confirm.level"),
    (["experiment.lca.dt=2"], "experiment.lca.dt"),
    (["experiment.step_deg=25"], "experiment.step_deg"),
    (["experiment.tests=[picture,sideways]"], "experiment.tests"),
]


@pytest.mark.parametrize("over,needle", BAD, ids=[" ".join(o) for o, _ in BAD])
def test_bad_settings_are_refused_before_any_work(tmp_path, capsys, monkeypatch, over, needle):
    from neuroimagery.app import cli

    def forbidden(*a, **k):
        raise AssertionError("training started before the input was refused")

    patch_experiment(monkeypatch, "exp6", train=forbidden)
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(evaluate)(make_cfg("experiment=exp6", *over), out_dir=tmp_path)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert ex.value.code == 2 and len(lines) == 1 and needle in lines[0], err


def test_mismatch_cluster_is_zero_for_identical_images_and_sees_a_missing_cube():
    """A bar of five cubes (2 voxels a side, graded code) against itself, against the bar without its
    end cube, and against that bar with the cube put apart instead."""
    from types import SimpleNamespace as NS

    side, cube = 18, 1.8

    def bar(cubes, apart=False):
        occ = torch.zeros(side, side, side)
        for k in range(cubes):
            occ[8:10, 8:10, 4 + 2 * k:6 + 2 * k] = 1.0
        if apart:
            occ[8:10, 14:16, 4:6] = 1.0
        return vc.graded(occ.reshape(1, -1), side, 0.7)

    model = NS(p=NS(confirm=NS(level=0.5)), side=side, cube_voxels=cube)
    full = bar(5)
    match, same = Rotation3D.mismatch(model, full, full)
    assert float(same) == 0.0 and float(match) == pytest.approx(1.0)
    _, missing = Rotation3D.mismatch(model, bar(4), full)
    _, moved = Rotation3D.mismatch(model, bar(4, apart=True), full)
    assert float(missing) >= 1.0 and float(moved) >= 1.0


def test_the_config_keeps_few_flat_keys():
    """The stimulus and view settings live in groups: at most 12 keys at the top level (groups apart)."""
    import dataclasses

    e = Exp6Config()
    flat = [f.name for f in dataclasses.fields(e) if not dataclasses.is_dataclass(getattr(e, f.name))]
    assert len(flat) <= 12, flat
    assert {"objects", "view"} <= {f.name for f in dataclasses.fields(e)} - set(flat)


EARLIER = ["experiment.object_seed=1", "experiment.test_cubes=null", "experiment.view_tilt_deg=10",
           "experiment.red_threshold=50", "experiment.move_rule=axis_sums", "experiment.confirm.measure=opened",
           "experiment.confirm.pool=0.5", "experiment.search.method=sweep", "experiment.search.starts=[20,40]",
           "experiment.search.keep=8"]


@pytest.mark.parametrize("over", EARLIER)
def test_keys_of_the_flat_layout_and_of_removed_options_are_refused(capsys, hydra_reporter, over):
    from support_bad_inputs import composing, refused

    refused(capsys, composing("experiment=exp6", over), over.split("=")[0])
