"""The stage contracts of Experiment 6 (docs/contracts.md, 6.1-6.4), measured on a trained model
with held-out random chains (a stream no training uses) and the training objects. Used by the
contract tests and written to ``summary.json`` (``stages``)."""
from __future__ import annotations


import torch

from ...models import voxel_code as vc
from ...core import progress
from ...nn import seeding
from ...vision import shepard_metzler as sm
from . import data as data

HELD_OUT = 90_000  # chain streams of the held-out checks (training uses stream 1000)


def completion(model, cfg, scene, count: int = 40) -> dict:
    """6.1: mean cosine of the completed map of a held-out chain view with its whole-volume map, per
    participant (and the seen surface's cosine, for comparison)."""
    e = cfg.experiment
    s, w, _, _ = data.chain_views(scene, e, model.side, model.cube_voxels, count, cfg.seed, HELD_OUT)
    P = model.participants
    part = torch.arange(P).repeat_interleave(count)
    code_s, code_w = model.encode(s), model.encode(w)
    filled = model.complete(code_s.repeat(P, 1), part).reshape(P, count, -1)
    cos = vc.cosine(filled, code_w.unsqueeze(0))
    return {"cosine": [round(float(c), 4) for c in cos.mean(1)],
            "surface_cosine": round(float(vc.cosine(code_s, code_w).mean()), 4)}


def transform(model, cfg, scene, count: int = 20) -> dict:
    """6.2: chained steps of each turning move on the whole-volume maps of held-out chains against the
    one-shot turn; and how often the same chain beats its mirror (same pose) after the chain."""
    e = cfg.experiment
    _, w, _, _ = data.chain_views(scene, e, model.side, model.cube_voxels, count, cfg.seed, HELD_OUT + 1)
    _, wm, _, _ = data.chain_views(scene, e, model.side, model.cube_voxels, count, cfg.seed, HELD_OUT + 1, mirror=True)
    X = vc.recentre(model.encode(w), model.side)
    M = vc.recentre(model.encode(wm), model.side)
    n = int(round(180.0 / e.step_deg))
    P = model.participants
    part = torch.arange(P).repeat_interleave(count)
    cos, beats = {}, []
    for m in range(1, len(model.moves)):
        axis, deg = model.moves[m]
        one = vc.rotate(X, model.side, vc.axis_rotation(axis, n * deg)).repeat(P, 1)
        x, xm = X.repeat(P, 1), M.repeat(P, 1)
        mv = torch.full((P * count,), m)
        for _ in range(n):
            x, xm = model.step(x, mv, part), model.step(xm, mv, part)
        c, cm = vc.cosine(x, one), vc.cosine(xm, one)
        cos[f"{axis}{'+' if deg > 0 else '-'}"] = round(float(c.mean()), 4)
        beats.append((c > cm).float())
    return {"steps": n, "cosine": cos, "same_above_mirror": round(float(torch.cat(beats).mean()), 4)}


def _pairs(model, cfg, scene, cells, kinds, angle_list, ids):
    names = [f"C{i}" for i in range(len(cells))]
    images, index = data.pair_bank(model, cfg, scene, cells, names, kinds, ids, lambda k: angle_list)
    rows = []
    for name, c in zip(names, cells):
        for kind in kinds:
            for ang in angle_list:
                for app in ("basic", "mirror"):
                    rows.append((index[(name, None, 0.0, "basic")], index[(name, kind, float(ang), app)], kind, float(ang),
                                 app == "basic"))
    return images, rows


def _true_required(kind: str, angle: float) -> torch.Tensor:
    """The rotation that turns the comparison view back onto the target (the stimulus's inverse)."""
    if kind == "oblique":
        R = torch.from_numpy(sm.rotation_about(sm.OBLIQUE_AXIS, angle))
    else:
        R = torch.from_numpy(sm.rotation_matrix(sm.KIND_AXIS[kind], angle))
    return R.T


def search(model, cfg, scene, count: int = 10) -> dict:
    """6.3: held-out chains as same pairs (general view, turned 20-180 deg in the picture plane or in
    depth): the estimate's angle within 20 deg and, from 40 deg on, its axis within 20 deg."""
    e = cfg.experiment
    cells = data.chains(e, count, cfg.seed, HELD_OUT + 2)
    angs = [a for a in e.test_angles if a > 0]
    ids = list(range(model.participants))
    images, rows = _pairs(model, cfg, scene, cells, sm.KINDS, angs, ids)
    rows = [r for r in rows if r[4]]
    out = {}
    P = model.participants
    for kind in sm.KINDS:
        rk = [r for r in rows if r[2] == kind]
        t = images[:, [r[0] for r in rk]].reshape(P * len(rk), -1)
        c = images[:, [r[1] for r in rk]].reshape(P * len(rk), -1)
        part = torch.arange(P).repeat_interleave(len(rk))
        R, _ = model.search(t, c, part)
        ax, ang = vc.axis_angle(R)
        truth = torch.stack([_true_required(kind, r[3]) for r in rk]).repeat(P, 1, 1)
        tax, tang = vc.axis_angle(truth)
        ang_ok = (ang - tang).abs() <= 20.0
        cosax = (ax * tax).sum(-1).clamp(-1, 1)
        axis_err = torch.rad2deg(torch.arccos(cosax))
        axis_err = torch.where(tang > 170.0, torch.minimum(axis_err, 180.0 - axis_err), axis_err)  # 180 deg: either sign
        axis_ok = (axis_err <= 20.0) | (tang < 40.0 - 1e-6)
        out[kind] = round(float((ang_ok & axis_ok).double().mean()), 4)
    return out


def alignment(model, cfg, scene, count: int = 6) -> dict:
    """The model's own search and transform on the protocol's pairs (picture plane and depth, the test
    angles, same and mirror) of the training objects (``train``) and of ``count`` held-out chains
    (``held_out``): per set the pairs' kinds, whether same, the true alignment (the stimulus's
    inverse), the comparison images and :meth:`Rotation3D.align`'s result. Shared by 6.2c, 6.3b and 6.4."""
    e = cfg.experiment
    train, _, _, _ = data.objects(e)
    held = data.chains(e, count, cfg.seed, HELD_OUT + 3)
    ids = list(range(model.participants))
    P = model.participants
    out = {}
    for label, cells in (("train", train), ("held_out", held)):
        images, rows = _pairs(model, cfg, scene, cells, sm.KINDS, list(e.test_angles), ids)
        gens = seeding.participant_generators(cfg.seed, ids, stream=60)
        res = model.align(images[:, [r[0] for r in rows]], images[:, [r[1] for r in rows]], gens)
        out[label] = {"kind": [r[2] for r in rows] * P, "same": torch.tensor([r[4] for r in rows]).repeat(P),
                      "truth": torch.stack([_true_required(r[2], r[3]) for r in rows]).repeat(P, 1, 1),
                      "comp": images[:, [r[1] for r in rows]].reshape(P * len(rows), -1), "res": res}
    return out


def _within_half_step(angle: torch.Tensor, cfg) -> torch.Tensor:
    """Whether each angle (deg) is at most half a forward-model step (``step_deg / 2``, with a hair
    of float tolerance): the precision contracts 6.2c, 6.3b and 6.4's alignment ask for."""
    return angle <= cfg.experiment.step_deg / 2 + 1e-6


def _frac(x: torch.Tensor) -> float:
    return round(float(x.double().mean()), 4) if x.numel() else float("nan")


def _by_kind(al: dict, ok: torch.Tensor, rows: torch.Tensor) -> dict:
    kinds = al["kind"]
    return {k: _frac(ok[rows & torch.tensor([x == k for x in kinds])]) for k in sm.KINDS}


def precision(model, cfg, scene, count: int = 6, al: dict | None = None) -> dict:
    """6.3b: per set (training objects, held-out chains) and kind, the fraction of same pairs whose
    estimate lies within half a step of the true alignment (the angle of the rotation between them)."""
    al = alignment(model, cfg, scene, count) if al is None else al
    out = {}
    for label, a in al.items():
        ok = _within_half_step(angle_between(a["res"]["required"], a["truth"]), cfg)
        out[label] = _by_kind(a, ok, a["same"])
    return out


def realisation(model, cfg, scene, count: int = 6, al: dict | None = None) -> dict:
    """6.2c: per set and kind, the fraction of same pairs whose net turn, composed from the steps'
    efference copies, ends within half a step of the search's estimate (``*_mirror``: mirror pairs)."""
    al = alignment(model, cfg, scene, count) if al is None else al
    out = {}
    for label, a in al.items():
        ok = _within_half_step(angle_between(a["res"]["net"], a["res"]["required"]), cfg)
        out[label] = _by_kind(a, ok, a["same"])
        out[f"{label}_mirror"] = _by_kind(a, ok, ~a["same"])
    return out


def confirm(model, cfg, scene, count: int = 6, al: dict | None = None) -> dict:
    """6.4: fraction of pairs the fitted cut puts on their side after the model's own search and
    transform, on the training objects' pairs and on held-out chains' pairs. Also where the errors
    arise: the fraction of same pairs whose net turn lands within half a step of the stimulus's
    inverse (``*_same_aligned``), of same pairs over the cut (``*_same_over``) and over it when
    their completed comparison image is turned exactly by the stimulus's inverse instead
    (``*_same_over_exact``: the completion's share), and of mirror pairs under the cut
    (``*_mirror_under``)."""
    al = alignment(model, cfg, scene, count) if al is None else al
    out = {}
    for label, a in al.items():
        res, same, truth = a["res"], a["same"], a["truth"]
        _, cubes = model.mismatch(res["turned"], res["target"])
        cut = model.cut.repeat_interleave(len(same) // model.participants)
        out[label] = _frac((cubes > cut) == ~same)
        out[f"{label}_cubes_same"] = round(float(cubes[same].mean()), 3)
        out[f"{label}_cubes_mirror"] = round(float(cubes[~same].mean()), 3)
        residual = angle_between(res["net"], truth)
        _, exact = model.mismatch(vc.rotate(a["comp"], model.side, truth), res["target"])
        out[f"{label}_same_aligned"] = _frac(_within_half_step(residual[same], cfg))
        out[f"{label}_same_over"] = _frac(cubes[same] > cut[same])
        out[f"{label}_same_over_exact"] = _frac(exact[same] > cut[same])
        out[f"{label}_mirror_under"] = _frac(cubes[~same] <= cut[~same])
    out["cut_cubes"] = [round(float(c), 3) for c in model.cut]
    return out


def measure(model, cfg, scene) -> dict:
    """Every stage contract's measure on small held-out sets (the contract tests use larger ones)."""
    out: dict = {}
    jobs = [("alignment", lambda: alignment(model, cfg, scene, 3)),
            ("image", lambda: completion(model, cfg, scene, 20)), ("transform", lambda: transform(model, cfg, scene, 6)),
            ("search", lambda: search(model, cfg, scene, 4)), ("confirm", lambda: confirm(model, cfg, scene, al=out["alignment"])),
            ("precision", lambda: precision(model, cfg, scene, al=out["alignment"])),
            ("realisation", lambda: realisation(model, cfg, scene, al=out["alignment"]))]
    with progress.bar(total=len(jobs), what="stage measures (docs/contracts.md)", unit="stage") as shown:
        for name, job in jobs:
            shown.set_postfix_str(name)
            out[name] = job()
            shown.update()
    del out["alignment"]
    return out


def angle_between(R1: torch.Tensor, R2: torch.Tensor) -> torch.Tensor:
    """Angle (deg) of the rotation taking ``R2`` to ``R1``."""
    return vc.axis_angle(R1 @ R2.transpose(-1, -2))[1]


