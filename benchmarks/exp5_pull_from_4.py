"""Why a learnt pull retrieves the toy from posture 4 (contract W3, derived rule D5 of docs/contracts.md).

    python benchmarks/exp5_pull_from_4.py --seed S --libraries 0,7,8   # per-library diagnosis
    python benchmarks/exp5_pull_from_4.py --grid                       # D5: posture 4 placements

Diagnosis: acquires the libraries ``--libraries`` of seed ``S`` exactly as
``python -m neuroimagery.experiments.exp5.world`` does (all six detectors, no brain) and prints, for
the pull (the skill of "retrieve"): the posture it was found from, the PI^BB samples that achieved
it from each posture in each epoch (the C1 teaching signals of Fig. 7.5 times K), the postures the
mean achieved it from after each epoch, the postures the movement as found already achieves it
from, the grip's peak speed from posture 1 and 4, and from posture 4 the side of the toy the plate
first comes near (``exp5_approach.first_approach``'s rule) and the events before the stop.

``--grid``: for posture 4 moved to plate centres on a grid on the toy's left (and two on its right),
fitted to a heading of the handle, by forward kinematics only: whether every scene criterion holds,
the share of exploration movements (2000, stream seed 7) that first approach the toy from its north
side (D3 needs more than 1 %), and the share of *pull paths behind* (D5): of the pulls of the 16
libraries of seed 7, those whose path from that posture brings a plate point north of the toy's far
face, within its y-span, below its top (the rake raised where the table stops it, as the kinematic
drive does).
"""
from __future__ import annotations

import argparse
import itertools
import math
from pathlib import Path

import numpy as np
import torch

import neuroimagery.models.tool_use.acquisition as acquisition
from neuroimagery.experiments.exp5.config import WorldParams
from neuroimagery.models.tool_use import EVENTS, AcquisitionParams, acquire_skills
from neuroimagery.robot.environment import ToolWorldEnvironment
from neuroimagery.robot.scene_check import plate_points

SIDES = ("north", "south", "west", "east")


def _approach():
    import importlib.util

    spec = importlib.util.spec_from_file_location("exp5_approach", Path(__file__).with_name("exp5/approach.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def library(env, seed: int, i: int):
    """Library ``i`` of ``seed`` as exp5_world acquires it, and each skill's parameters as found."""
    found: dict[str, torch.Tensor] = {}
    learn = acquisition._learn_skill

    def keep_found(env_, skill, *rest):
        found[skill.event] = skill.theta.clone()
        return learn(env_, skill, *rest)

    acquisition._learn_skill = keep_found
    try:
        g = torch.Generator().manual_seed(seed * 100003 + i)
        return acquire_skills(env, EVENTS, AcquisitionParams(), g, brain=None), found
    finally:
        acquisition._learn_skill = learn


def paths(env, theta: torch.Tensor, q0: torch.Tensor) -> np.ndarray:
    """Rake poses (N, T, 4, 4) of the DMPs ``theta`` (N, P) rolled out from ``q0``."""
    w = env.world
    traj = w.kin.clamp(env.dmp.rollout(theta.float(), q0, env.duration_s, env.dt))
    return w.kin.rake_pose_np(traj.double().numpy())


def first_side(cfg, poses: np.ndarray) -> str:
    pts = np.einsum("tij,pj->tpi", poses, plate_points(cfg))[..., :3]
    (tx, ty), h = cfg.toy_xy, cfg.toy_size / 2
    dx, dy = pts[..., 0] - tx, pts[..., 1] - ty
    near = (pts[..., 2] < cfg.table_top + cfg.toy_size - 0.01) & (np.maximum(abs(dx), abs(dy)) < h + 0.03)
    hit = near.any(axis=1)
    if not hit.any():
        return "none"
    t = int(np.argmax(hit))
    m = near[t]
    side = np.where(abs(dx[t][m]) >= abs(dy[t][m]), np.where(dx[t][m] > 0, 0, 1), np.where(dy[t][m] > 0, 2, 3))
    return SIDES[int(np.bincount(side, minlength=4).argmax())]


def diagnose(seed: int, ids: list[int]) -> None:
    w = WorldParams()
    for i in ids:
        env = ToolWorldEnvironment(w.world_config(), **w.env_kwargs())
        try:
            lib, found = library(env, seed, i)
            for s in (s for s in lib.skills if s.event == "retrieve"):
                c1 = [round(op[2] * AcquisitionParams().pibb_samples) for op in s.log if op[0] == "c1"]
                means, now = [], None
                for op in s.log:
                    if op[0] == "c1" and op[1] == 1:
                        now = []
                        means.append(now)
                    elif op[0] == "c23":
                        now.append(op[1])
                as_found = [env.execute(found["retrieve"][None], env.start(p), "retrieve")[0].retrieved for p in range(1, 5)]
                speed = []
                for p in (1, 4):
                    c = paths(env, s.theta[None], env.world.initial_posture(p))[0, :, :3, 3]
                    speed.append(float(np.linalg.norm(np.diff(c, axis=0), axis=1).max() / env.dt))
                r = env.execute(s.theta[None], env.start(4), "retrieve")[0]
                order = [e.name for e in lib.skills]
                print(f"seed {seed} library {i}: skills {order}; pull found from posture {s.found_from}\n"
                      f"  samples achieving it per epoch, postures 1-4: {[c1[k:k + 4] for k in range(0, len(c1), 4)]}\n"
                      f"  mean achieves it after each epoch from {means}; as found from {[p for p, ok in zip(range(1, 5), as_found) if ok]}\n"
                      f"  grip peak speed from posture 1 / 4: {speed[0]:.2f} / {speed[1]:.2f} m/s; from posture 4: first near the toy's "
                      f"{first_side(env.world.cfg, paths(env, s.theta[None], env.world.initial_posture(4))[0])} side, "
                      f"events {[e for e, f in zip(EVENTS, r.events) if f]}", flush=True)
        finally:
            env.close()


def grid() -> None:
    from neuroimagery.robot.config import WorldConfig
    from neuroimagery.robot.posture_fit import HEADING_STARTS, fit_posture_heading
    from neuroimagery.robot.scene_check import check_scene, scene_geometry

    w = WorldParams()
    env = ToolWorldEnvironment(w.world_config(), **w.env_kwargs())
    try:
        pulls = torch.stack([s.theta for i in range(16) for s in library(env, 7, i)[0].skills if s.event == "retrieve"])
    finally:
        env.close()
    cfg = WorldConfig()
    approach = _approach()
    kin = approach.ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                                 rake_head_offset=tuple(cfg.rake_head_offset))
    pts_rake = plate_points(cfg)[::3]
    (tx, ty), h = cfg.toy_xy, cfg.toy_size / 2
    env = ToolWorldEnvironment(w.world_config(), **w.env_kwargs())

    def behind(q) -> float:
        pts = np.einsum("ntij,pj->ntpi", paths(env, pulls, torch.tensor(q, dtype=torch.float32)), pts_rake)[..., :3]
        lift = np.maximum(0.0, cfg.table_top + cfg.table_clearance - pts[..., 2].min(axis=2, keepdims=True))
        b = (pts[..., 0] > tx + h) & (abs(pts[..., 1] - ty) < h) & (pts[..., 2] + lift < cfg.table_top + cfg.toy_size)
        return float(b.any(axis=(1, 2)).mean())

    targets = [((x, y), yaw) for x, y, yaw in itertools.product((0.42, 0.46, 0.50, 0.54), (0.18, 0.22, 0.26), (0.0, 30.0))]
    targets += [((0.50, -0.40), 0.0), ((0.50, -0.40), -30.0)]
    print(f"{len(pulls)} pulls (seed 7)\n| plate centre | handle (deg left) | criteria | gap (m) | north approach | pull paths behind |\n"
          "|---|---|---|---|---|---|")
    print(f"| posture 4 now | - | met | {scene_geometry(cfg)[3]['gap']:.3f} | "
          f"{approach.first_approach(kin, cfg, cfg.postures[3], 2000)['north']:.2%} | {behind(cfg.postures[3]):.0%} |", flush=True)
    try:
        for xy, yaw in targets:
            q = fit_posture_heading(cfg, xy, yaw, HEADING_STARTS + tuple(cfg.postures[1:]))
            postures = list(cfg.postures)
            postures[3] = tuple(round(float(v), 3) for v in q)
            new = WorldConfig(postures=tuple(postures))
            g = scene_geometry(new)[3]
            ok = math.hypot(g["head_xy"][0] - xy[0], g["head_xy"][1] - xy[1]) <= 0.01 and not check_scene(new)
            print(f"| {xy} | {yaw:.0f} | {'met' if ok else 'not met'} | {g['gap']:.3f} | "
                  f"{approach.first_approach(kin, cfg, postures[3], 2000)['north']:.2%} | {behind(postures[3]):.0%} |", flush=True)
    finally:
        env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--libraries", default="0,7,8,13,14", help="comma-separated library numbers")
    parser.add_argument("--grid", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.grid:
        grid()
    else:
        diagnose(args.seed, [int(v) for v in args.libraries.split(",")])


if __name__ == "__main__":
    main()
