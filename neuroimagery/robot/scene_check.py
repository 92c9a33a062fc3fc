"""The geometric criteria of the tool-use scene (docs/robot.md, "Scene criteria"), measured.

``scene_geometry(cfg)`` measures, by forward kinematics only (no physics), what each criterion is
about at every initial posture: the gap between the rake head's plate and the toy, whether the
plate lies behind the toy, how far the handle clears the toy's top, how high the plate rests and
how far each joint is from its limits; ``check_scene(cfg)`` returns the criteria that fail (an empty
list: the scene meets them). ``python -m neuroimagery.robot.scene_check`` prints both.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.arguments import ToolParser, run_tool
from .config import WorldConfig

PLATE_PITCH = -0.4363323  # the plate's pitch about the rake's y axis (urdf/rake.urdf)
HANDLE_RADIUS = 0.008


def plate_points(cfg: WorldConfig) -> np.ndarray:
    hx, hy, hz = cfg.rake_head_offset
    c, s = math.cos(PLATE_PITCH), math.sin(PLATE_PITCH)
    PLATE = cfg.rake_plate
    pts = []
    for dx in np.linspace(-PLATE[0] / 2, PLATE[0] / 2, 3):
        for dy in np.linspace(-PLATE[1] / 2, PLATE[1] / 2, 33):
            for dz in np.linspace(-PLATE[2] / 2, PLATE[2] / 2, 11):
                pts.append((hx + c * dx + s * dz, hy + dy, hz - s * dx + c * dz, 1.0))
    return np.array(pts)


def scene_geometry(cfg: WorldConfig | None = None, frontier=None) -> list[dict]:
    """One dict per posture (1..4): ``gap``, ``behind`` (plate within the toy's y-span north of
    it), ``near_face_beyond`` (posture 1: how far the plate's near face lies beyond the toy's
    north face), ``plate_dy`` (plate centre's y minus the toy's), ``handle_clearance`` (handle's
    lowest point over the toy's footprint minus the toy's top; inf if not over it),
    ``plate_height`` (plate's lowest point above the table) and ``joint_margin`` (smallest
    distance of a joint to its limits, as a share of its range)."""
    from .kinematics import ArmKinematics
    import torch

    cfg = cfg or WorldConfig()
    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    tx, ty = cfg.toy_xy
    h = cfg.toy_size / 2
    top = cfg.table_top + cfg.toy_size
    plate = plate_points(cfg)
    handle = np.array([(x, 0.0, 0.0, 1.0) for x in np.linspace(0.0, cfg.rake_length, 161)])
    lim = kin.joint_limits.double().numpy()
    out = []
    for k, q in enumerate(cfg.postures, start=1):
        T = kin.rake_pose_np(np.array(q, dtype=np.float32)[None])[0]
        P = (plate @ T.T)[:, :3]
        H = (handle @ T.T)[:, :3]
        lo = np.array([tx - h, ty - h, cfg.table_top])
        hi = np.array([tx + h, ty + h, top])
        d = np.maximum(np.maximum(lo - P, P - hi), 0.0)
        gap = float(np.sqrt((d * d).sum(-1)).min())
        span = np.abs(P[:, 1] - ty) < h
        north = span & (P[:, 0] > tx + h)
        over = (np.abs(H[:, 0] - tx) < h + HANDLE_RADIUS) & (np.abs(H[:, 1] - ty) < h + HANDLE_RADIUS)
        clearance = float((H[over, 2] - HANDLE_RADIUS).min() - top) if over.any() else math.inf
        centre = (np.array([*cfg.rake_head_offset, 1.0]) @ T.T)[:3]
        margin = float(np.min(np.minimum(np.array(q) - lim[:, 0], lim[:, 1] - np.array(q)) / (lim[:, 1] - lim[:, 0])))
        out.append(dict(posture=k, head_xy=(round(float(centre[0]), 3), round(float(centre[1]), 3)), gap=round(gap, 4),
                        plate_x_max=round(float(P[:, 0].max()), 4),
                        plate_y_span=(round(float(P[:, 1].min()), 4), round(float(P[:, 1].max()), 4)),
                        handle_over=int(over.sum()),
                        behind=bool(north.any()),
                        near_face_beyond=round(float(P[span, 0].min() - (tx + h)), 4) if span.any() else None,
                        plate_dy=round(float(centre[1] - ty), 4), handle_clearance=round(clearance, 4),
                        plate_height=round(float(P[:, 2].min() - cfg.table_top), 4), joint_margin=round(margin, 3)))
    return out


def check_scene(cfg: WorldConfig | None = None, derived: bool = True) -> list[str]:
    """The scene criteria of docs/robot.md that ``cfg`` fails (empty: all are met). ``derived=False``
    leaves out the two derived rules that the world's calibration searches over
    (docs/world_calibration.md): W6's whole plate of postures 3-4 on the robot's side of the toy's
    far face, and posture 4's gap at least the plate's width."""
    cfg = cfg or WorldConfig()
    g = scene_geometry(cfg)
    bad = []
    p1 = g[0]
    if not (p1["behind"] and p1["near_face_beyond"] is not None and 0.005 <= p1["near_face_beyond"] <= 0.03):
        bad.append(f"posture 1: the plate's near face must lie 0.5-3 cm beyond the toy's north face, got {p1['near_face_beyond']}")
    tx, ty = cfg.toy_xy
    h = cfg.toy_size / 2
    lo, hi = p1["plate_y_span"]
    if not (lo <= ty - h and hi >= ty + h):
        bad.append(f"posture 1: the plate must span the toy's width (y {ty - h:.3f}..{ty + h:.3f}), got {lo}..{hi}")
    if p1["handle_over"] > 0:  # W7: touch impossible from posture 1
        bad.append(f"posture 1: the handle must pass beside the toy, not over it ({p1['handle_over']} handle points over it)")
    for p in g[1:]:
        if p["behind"]:
            bad.append(f"posture {p['posture']}: the plate must not lie behind the toy")
    for p in g[2:] if derived else ():  # W6: no plate point of postures 3-4 beyond the toy's far face (whole plate)
        if p["plate_x_max"] > tx + h:
            bad.append(f"posture {p['posture']}: no point of the plate may lie beyond the toy's far face "
                       f"(x {tx + h:.3f}), got {p['plate_x_max']}")
    gaps = [p["gap"] for p in g]
    if not all(a < b for a, b in zip(gaps, gaps[1:])):
        bad.append(f"the gaps must grow from posture 1 to 4, got {gaps}")
    if derived and gaps[3] < 0.16:
        bad.append(f"posture 4: the gap must be at least the plate's width (0.16 m), got {gaps[3]}")
    for p in g:
        if p["handle_clearance"] < 0.02:
            bad.append(f"posture {p['posture']}: the handle must clear the toy's top by 2 cm, got {p['handle_clearance']}")
        if not 0.0 <= p["plate_height"] <= 0.01:
            bad.append(f"posture {p['posture']}: the plate must rest within 1 cm of the table, got {p['plate_height']}")
        if p["joint_margin"] < 0.10:
            bad.append(f"posture {p['posture']}: every joint 10 % of its range from a limit, got {p['joint_margin']}")
    if not tx - cfg.reach_frontier_at(ty) >= cfg.toy_size:
        bad.append(f"the toy must start at least {cfg.toy_size} m beyond the reachable area, "
                   f"got {tx - cfg.reach_frontier_at(ty):.3f}")
    return bad


def main(argv: list[str] | None = None) -> int:
    return run_tool(_main, argv)


def _main(argv: list[str] | None) -> int:
    ToolParser(prog="python -m neuroimagery.robot.scene_check", description=__doc__.split("\n")[0]).parse_args(argv)
    for row in scene_geometry():
        print(row)
    print("\n".join(check_scene()) or "all scene criteria met")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
