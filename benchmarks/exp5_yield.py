"""Whether the default table rule (``table_contact = lift``) is an arm that yields upward (docs/robot.md,
"Reading the lift: an arm that yields upward?").

    python benchmarks/exp5_yield.py [--rollouts 2000] [--seed 0]

For each posture, the exploration movements of ``python -m neuroimagery.robot.babble``'s seed
``--seed`` (the world's exploration rule W9, the same stream and batches of 50; each movement to its
end, no physics) are put through the world's table rule (``ToolWorld._plan``). For every control
step whose rake pose the lift raises, damped least squares on the seven arm joints of
``robot/kinematics.py``, kept within the URDF joint limits (a joint at a limit that the step would
push beyond it is held there), starting from the commanded joints, looks for a configuration that
puts the hand at the lifted hand pose: the commanded hand pose raised by the lift (the rake rigid
in the hand). A step is *reachable* when the solution is within 5 mm in position and 2 degrees in
orientation; where the start from the commanded joints fails, starts drawn uniformly within the
limits are tried too. Printed per posture: lifted steps (share of all steps, the lift's median and
90th percentile), the share reachable, and the joint deflection of the reachable ones (the largest
change of one joint from the commanded configuration; median and 90th percentile, degrees).
"""
from __future__ import annotations

import argparse
import math

import numpy as np
import torch

from neuroimagery.robot.kinematics import ArmKinematics
from neuroimagery.robot.movements import MovementConfig, explore, random_primitives, trajectories, world_dmp
from neuroimagery.robot.world import ToolWorld

POS_TOL, ROT_TOL = 0.005, math.radians(2.0)


def movements(world, posture: int, n: int, seed: int) -> torch.Tensor:
    """The joint trajectories (n, T, 7) of babble's stream ``seed`` from ``posture``."""
    dmp, mc = world_dmp(), MovementConfig()
    gen = torch.Generator().manual_seed(seed * 1009 + posture)  # robot.babble.babble_counts
    q0 = world.initial_posture(posture)
    out = []
    for start in range(0, n, 50):
        theta = explore(world, dmp, random_primitives(world, dmp, min(50, n - start), mc, gen), q0, gen)
        out.append(trajectories(world, dmp, theta, q0, mc))
    return torch.cat(out)


def _rotvec(R: torch.Tensor) -> torch.Tensor:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3)."""
    cos = ((R.diagonal(dim1=-2, dim2=-1).sum(-1) - 1) / 2).clamp(-1, 1)
    angle = torch.acos(cos)
    v = torch.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    s = torch.sin(angle)
    scale = torch.where(s > 1e-6, angle / (2 * s.clamp_min(1e-12)), torch.full_like(s, 0.5))
    return v * scale[..., None]


def ik(kin: ArmKinematics, target: torch.Tensor, q: torch.Tensor, iters: int = 150, damping: float = 0.02,
       max_step: float = 0.2) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Damped least squares from ``q`` (M, 7) to hand poses ``target`` (M, 4, 4) within the joint
    limits -> joints, position error (m), orientation error (rad)."""
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    Rwc = kin.world_T_chest[:3, :3]
    q = kin.clamp(q.clone())
    active = torch.ones(len(q), dtype=torch.bool)
    for _ in range(iters + 1):
        H = kin(q)
        ep = target[:, :3, 3] - H[:, :3, 3]
        eo = _rotvec(target[:, :3, :3] @ H[:, :3, :3].transpose(-1, -2))
        active = (ep.norm(dim=-1) > 0.5 * POS_TOL) | (eo.norm(dim=-1) > 0.5 * ROT_TOL)
        if not active.any() or _ == iters:
            break
        idx = active.nonzero().flatten()
        J = kin.arm.jacobian(q[idx])  # (m, 6, 7) in the chest frame, at the hand's origin
        J = torch.cat([Rwc @ J[:, :3], Rwc @ J[:, 3:]], 1)
        e = torch.cat([ep[idx], eo[idx]], -1)[..., None]
        eye = damping ** 2 * torch.eye(6, dtype=q.dtype)
        for _pass in range(2):  # a joint at a limit that the step pushes beyond it is held
            dq = (J.transpose(1, 2) @ torch.linalg.solve(J @ J.transpose(1, 2) + eye, e))[..., 0]
            qi = q[idx]
            stuck = ((qi <= lo + 1e-9) & (dq < 0)) | ((qi >= hi - 1e-9) & (dq > 0))
            if not stuck.any():
                break
            J = J * (~stuck)[:, None, :]
        n = dq.abs().amax(-1, keepdim=True)
        dq = dq * torch.clamp(max_step / n.clamp_min(1e-12), max=1.0)
        q[idx] = kin.clamp(q[idx] + dq)
    H = kin(q)
    return q, (target[:, :3, 3] - H[:, :3, 3]).norm(dim=-1), _rotvec(target[:, :3, :3] @ H[:, :3, :3].transpose(-1, -2)).norm(dim=-1)


def measure(world, kin: ArmKinematics, posture: int, n: int, seed: int, restarts: int = 4, chunk: int = 20000) -> dict:
    traj = movements(world, posture, n, seed).double()
    cmd = world.kin.rake_pose_np(traj.numpy())
    lifted = world._plan(traj.numpy())["poses"]
    lift = lifted[..., 2, 3] - cmd[..., 2, 3]
    sel = lift > 0
    q_cmd = traj[torch.from_numpy(sel)]
    hand = kin(q_cmd)
    target = hand.clone()
    target[:, 2, 3] += torch.from_numpy(lift[sel])
    ok = torch.zeros(len(q_cmd), dtype=torch.bool)
    defl = torch.full((len(q_cmd),), float("nan"), dtype=torch.float64)
    g = torch.Generator().manual_seed(12345 + posture)
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    for s in range(0, len(q_cmd), chunk):
        sl = slice(s, s + chunk)
        q, ep, eo = ik(kin, target[sl], q_cmd[sl])
        good = (ep <= POS_TOL) & (eo <= ROT_TOL)
        best = torch.where(good, (q - q_cmd[sl]).abs().amax(-1), torch.full_like(ep, float("inf")))
        for _ in range(restarts):  # starts drawn within the limits, for the steps still unreached
            miss = (~good).nonzero().flatten()
            if not len(miss):
                break
            start = lo + (hi - lo) * torch.rand(len(miss), 7, generator=g, dtype=torch.float64)
            q2, ep2, eo2 = ik(kin, target[sl][miss], start)
            g2 = (ep2 <= POS_TOL) & (eo2 <= ROT_TOL)
            d2 = (q2 - q_cmd[sl][miss]).abs().amax(-1)
            best[miss] = torch.where(g2, torch.minimum(best[miss], d2), best[miss])
            good[miss] |= g2
        ok[sl] = good
        defl[sl] = torch.where(good, best, torch.full_like(best, float("nan")))
    d = np.degrees(defl[ok].numpy())
    lifts = lift[sel]
    return {"steps": int(sel.size), "lifted": int(sel.sum()), "lift_cm": (np.median(lifts) * 100, np.percentile(lifts, 90) * 100),
            "reachable": int(ok.sum()), "deflection_deg": (np.median(d), np.percentile(d, 90)) if len(d) else (math.nan, math.nan),
            "over_5mm": int((lifts > POS_TOL).sum()), "reachable_over_5mm": int(ok[torch.from_numpy(lifts > POS_TOL)].sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--postures", default="1,2,3,4")
    args = parser.parse_args()
    torch.set_num_threads(1)
    with ToolWorld() as world:
        assert world.cfg.table_contact == "lift"
        cfg = world.cfg
        kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float64),
                            rake_head_offset=tuple(cfg.rake_head_offset), dtype=torch.float64)
        print("| posture | lifted steps (share of all) | lift, median / 90th pct (cm) | reachable | "
              "lifted more than 5 mm: reachable | joint deflection, median / 90th pct (deg) |\n|---|---|---|---|---|---|",
              flush=True)
        total = [0, 0]
        for k in (int(x) for x in args.postures.split(",")):
            r = measure(world, kin, k, args.rollouts, args.seed)
            total[0] += r["lifted"]
            total[1] += r["reachable"]
            print(f"| {k} | {r['lifted']} ({r['lifted'] / r['steps']:.1%}) | {r['lift_cm'][0]:.1f} / {r['lift_cm'][1]:.1f} | "
                  f"{r['reachable'] / max(r['lifted'], 1):.1%} | {r['reachable_over_5mm']} of {r['over_5mm']} "
                  f"({r['reachable_over_5mm'] / max(r['over_5mm'], 1):.1%}) | "
                  f"{r['deflection_deg'][0]:.1f} / {r['deflection_deg'][1]:.1f} |", flush=True)
        print(f"\nall postures: {total[1]} of {total[0]} lifted steps reachable ({total[1] / max(total[0], 1):.1%})")


if __name__ == "__main__":
    main()
