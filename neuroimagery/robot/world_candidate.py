"""A candidate tool-use world of the calibration (docs/world_calibration.md): the parameters the
thesis leaves open, turned into a complete ``WorldConfig`` through inverse kinematics.

``PARAMETERS`` names each parameter and its range (the page's table); :func:`build` takes one value
of each, fits the four postures (``robot.posture_fit.fit_posture_heading``: a plate-centre target,
a heading of the handle, the elbow's swivel), writes the rake of the candidate's size into a folder
of URDFs and returns the world with what the fit reached; posture 1 is placed first and the toy
derived from it (docs/world_calibration.md, third amendment). :func:`reject_reasons` is stage 1's
scene part (the criteria of Fig. 7.2, ``robot.scene_check`` without the two derived rules the
calibration searches over); the pull paths are ``robot.pull_paths``.
"""
from __future__ import annotations

import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np

from .config import DEFAULT_POSTURES, URDF_DIR, WorldConfig

# name: (low, high) of a float, or a tuple of choices (docs/world_calibration.md, "Parameters")
PARAMETERS: dict[str, tuple] = {
    "toy_dx": (0.05, 0.11), "toy_y": (-0.20, 0.00),
    "rake_length": (0.36, 0.48), "plate_width": (0.12, 0.20),
    "p1_gap": (0.005, 0.03), "p1_dy": (-0.05, 0.05),
    "r_2": (0.07, 0.20), "dr_3": (0.0, 0.15), "dr_4": (0.0, 0.15),
    **{f"dir_{k}": (-180.0, 180.0) for k in (2, 3, 4)},
    **{f"yaw_{k}": (-45.0, 60.0) for k in (1, 2, 3, 4)},
    **{f"pitch_{k}": (15.0, 40.0) for k in (1, 2, 3, 4)},
    **{f"swivel_{k}": (0.0, 1.0) for k in (1, 2, 3, 4)},
    "goal_noise_share": (0.05, 0.20), "weight_sigma": (100.0, 600.0),
    "table_contact": ("lift", "grip", "yield"), "grip_pivot_deg": (5.0, 60.0),
}
# the present world (docs/robot.md) re-expressed in these parameters: its toy, posture 1's near
# face and plate offset, the plate centres of postures 2-4 and its rake; postures 1 and 2 turned to
# a heading of 0 (the present ones keep a reference orientation)
PRESENT = dict(toy_dx=0.059, toy_y=-0.10, rake_length=0.40, plate_width=0.16, p1_gap=0.0154, p1_dy=-0.035,
               r_2=0.16, dr_3=0.021, dr_4=0.102, dir_2=-86.0, dir_3=96.0, dir_4=98.0,
               yaw_1=0.0, yaw_2=0.0, yaw_3=0.0, yaw_4=30.0, pitch_1=25.0, pitch_2=25.0, pitch_3=25.0, pitch_4=25.0,
               swivel_1=0.5, swivel_2=0.5, swivel_3=0.5, swivel_4=0.5, goal_noise_share=0.1, weight_sigma=300.0,
               table_contact="lift", grip_pivot_deg=10.0)
FIT_TOLERANCE = 0.01  # m: a posture whose plate centre misses its target by more rejects the candidate
HEAD_BEYOND_HANDLE = 0.0148  # m: the plate's centre lies this far past the handle's end (urdf/rake.urdf)


def rake_urdf(length: float, width: float) -> str:
    """``urdf/rake.urdf`` with the handle ``length`` long and the plate ``width`` wide (the plate's
    thickness, height and pitch, and where the handle meets it, unchanged)."""
    text = (Path(URDF_DIR) / "rake.urdf").read_text()
    hx = length + HEAD_BEYOND_HANDLE
    for old, new in (('xyz="0.25 0 0"', f'xyz="{0.625 * length:.4f} 0 0"'),
                     ('xyz="0.20 0 0"', f'xyz="{length / 2:.4f} 0 0"'),
                     ('length="0.40"', f'length="{length:.4f}"'),
                     ('xyz="0.4148 0 -0.0317"', f'xyz="{hx:.4f} 0 -0.0317"'),
                     ('size="0.02 0.16 0.08"', f'size="0.02 {width:.4f} 0.08"')):
        if old not in text:
            raise ValueError(f"urdf/rake.urdf no longer has {old}: update robot.world_candidate.rake_urdf")
        text = text.replace(old, new)
    return text


def write_urdfs(folder: Path, length: float, width: float) -> Path:
    """A folder of the world's URDFs with the candidate's rake (table and toy copied)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("table.urdf", "toy.urdf"):
        shutil.copyfile(Path(URDF_DIR) / name, folder / name)
    (folder / "rake.urdf").write_text(rake_urdf(length, width))
    return folder


def targets(cfg: WorldConfig, p: dict) -> list[tuple[float, float]]:
    """The plate-centre targets of postures 2-4 around ``cfg``'s toy (docs/world_calibration.md)."""
    (tx, ty) = cfg.toy_xy
    out = []
    r = p["r_2"]
    for k in (2, 3, 4):
        r += p.get(f"dr_{k}", 0.0)
        a = math.radians(p[f"dir_{k}"])
        out.append((tx + r * math.cos(a), ty + r * math.sin(a)))
    return out


def base_config(p: dict, urdf_dir: Path) -> WorldConfig:
    """Every setting of the candidate but the postures (kept at the present ones until fitted)."""
    ty = float(p["toy_y"])
    probe = WorldConfig()
    tx = probe.reach_frontier_at(ty) + float(p["toy_dx"])
    table = p["table_contact"]
    return replace(probe, toy_xy=(round(tx, 4), round(ty, 4)), rake_length=float(p["rake_length"]),
                   rake_head_offset=(float(p["rake_length"]) + HEAD_BEYOND_HANDLE, 0.0, -0.0317),
                   rake_plate=(0.02, float(p["plate_width"]), 0.08), goal_noise_share=float(p["goal_noise_share"]),
                   table_contact=table,
                   grip_pivot_max=math.radians(float(p["grip_pivot_deg"])) if table == "grip" else probe.grip_pivot_max,
                   urdf_dir=str(urdf_dir))


def _starts() -> tuple:
    from .posture_fit import HEADING_STARTS

    return HEADING_STARTS + tuple(DEFAULT_POSTURES)


def plate_centre(cfg: WorldConfig, q) -> tuple[float, float]:
    import torch

    from .kinematics import ArmKinematics

    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    c = kin.rake_pose_np(np.asarray(q, dtype=np.float64)[None])[0] @ np.array([*cfg.rake_head_offset, 1.0])
    return float(c[0]), float(c[1])


def regions(cfg: WorldConfig, xy: np.ndarray) -> list[np.ndarray]:
    """Where the plate centres of postures 2-4 may be placed (docs/world_calibration.md, second
    amendment): posture k within r_k's range of the toy."""
    (tx, ty) = cfg.toy_xy
    r = np.hypot(xy[:, 0] - tx, xy[:, 1] - ty)
    r_lo, r_hi = PARAMETERS["r_2"]
    return [(r >= r_lo) & (r <= r_hi + (k - 2) * PARAMETERS["dr_3"][1]) for k in (2, 3, 4)]


def _fit(cfg, xy, yaw, pitch, swivel, starts):
    from .posture_fit import fit_posture_heading

    q = tuple(round(float(v), 4) for v in fit_posture_heading(cfg, xy, yaw, starts, pitch_deg=pitch, swivel=swivel))
    return q, math.dist(plate_centre(cfg, q), xy)


def implied_toys(cfg: WorldConfig, q: np.ndarray, p1_dy: float, p1_gap: float, points=None) -> np.ndarray:
    """(N, 2): the toy place each joint vector of ``q`` (N, 7) implies as posture 1 (docs/
    world_calibration.md, third amendment): y = its plate centre's y - ``p1_dy``; the toy's far face
    ``p1_gap`` nearer than the plate's nearest point within that y-span (x NaN where no plate point
    lies within it). ``points``: the plate's points (default ``scene_check.plate_points``)."""
    from .kinematics import ArmKinematics
    from .scene_check import plate_points

    import torch

    pts = plate_points(cfg) if points is None else points
    kin = ArmKinematics(root_height=cfg.root_height, grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
                        rake_head_offset=tuple(cfg.rake_head_offset))
    T = kin.rake_pose_np(np.asarray(q, dtype=np.float32).reshape(-1, 7))
    P = np.einsum("nij,pj->npi", T[:, :3], pts)
    h = cfg.toy_size / 2
    ty = (T[:, :3] @ np.array([*cfg.rake_head_offset, 1.0]))[:, 1] - p1_dy
    near = np.where(np.abs(P[..., 1] - ty[:, None]) < h, P[..., 0], np.inf).min(axis=1)
    tx = np.where(np.isfinite(near), near - p1_gap - h, np.nan)
    return np.stack([tx, ty], axis=1)


def toy_in_ranges(cfg: WorldConfig, toys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each toy place (N, 2) lies in the written ranges (``toy_dx`` beyond the reachable
    area's far edge at its y, ``toy_y``), and its ``toy_dx``."""
    tx, ty = toys[:, 0], toys[:, 1]
    known = np.isfinite(tx) & np.isfinite(ty)
    dx = np.full(len(toys), np.nan)
    dx[known] = tx[known] - np.array([cfg.reach_frontier_at(y) for y in ty[known]])
    (lo, hi), (ylo, yhi) = PARAMETERS["toy_dx"], PARAMETERS["toy_y"]
    with np.errstate(invalid="ignore"):
        return known & (dx >= lo) & (dx <= hi) & (ty >= ylo) & (ty <= yhi), dx


def _posture_1(cfg: WorldConfig, table, p: dict, placed: list):
    """Posture 1 placed first as a row of the reachability table and the toy derived from it (third
    amendment): (the world with the derived toy, posture 1's joint vector or None, reasons)."""
    from .reachability import nearest
    from .scene_check import plate_points

    rows, x = table
    edges = plate_points(cfg).reshape(3, 33, 11, 4)[::2, :, ::10].reshape(-1, 4)  # thickness, height extremes
    toys = implied_toys(cfg, rows, p["p1_dy"], p["p1_gap"], edges)
    found = nearest(np.column_stack([toys, x[:, 2:]]), [*cfg.toy_xy, p["yaw_1"], p["pitch_1"]],
                    toy_in_ranges(cfg, toys)[0])
    if found is None:
        return cfg, None, ["posture 1: no reachable plate with the toy in its ranges"]
    i, units = found
    row = (tuple(x[i, :2]), float(x[i, 2]), float(x[i, 3]))
    if units <= 1.0:  # the sample keeps its value
        xy, yaw, pitch = tuple(x[i, :2] + np.asarray(cfg.toy_xy) - toys[i]), p["yaw_1"], p["pitch_1"]
    else:
        xy, yaw, pitch = row
    q, miss = _fit(cfg, xy, yaw, pitch, p["swivel_1"], _starts() + (tuple(rows[i]),))
    moved = units > 1.0
    if miss > FIT_TOLERANCE:  # moved onto the row and fitted from it
        (xy, yaw, pitch), moved = row, True
        q, miss = _fit(cfg, xy, yaw, pitch, p["swivel_1"], (tuple(rows[i]),))
    placed.append(dict(target=[round(float(v), 4) for v in xy], yaw=round(float(yaw), 2), pitch=round(float(pitch), 2),
                       moved=moved, row_units=round(units, 3), toy_sampled=[p["toy_dx"], p["toy_y"]]))
    if miss > FIT_TOLERANCE:
        return cfg, q, [f"posture 1: the fit misses its plate-centre target by {miss:.3f} m"]
    toy = implied_toys(cfg, np.asarray(q), p["p1_dy"], p["p1_gap"])
    inside, dx = toy_in_ranges(cfg, toy)
    placed[0]["toy_derived"] = [round(float(dx[0]), 4), round(float(toy[0, 1]), 4)]
    if np.isnan(toy[0, 0]):
        return cfg, q, ["posture 1: no plate point within the toy's y-span"]
    if not inside[0]:
        return cfg, q, [f"the toy's place derived from posture 1 lies outside its ranges: toy_dx {dx[0]:.3f}, "
                        f"toy_y {toy[0, 1]:.3f}"]
    return replace(cfg, toy_xy=(float(toy[0, 0]), float(toy[0, 1]))), q, []


def build(p: dict, urdf_dir: Path, placed: list | None = None) -> tuple[WorldConfig, list[str]]:
    """The candidate world of parameters ``p`` (its rake written into ``urdf_dir``) and the reasons
    it is rejected by its postures (empty: every target met within ``FIT_TOLERANCE``). Posture 1 is
    placed first and the toy derived from it (:func:`_posture_1`); each of postures 2-4 is fitted
    from the stored starts and the reachability table's nearest row around that toy, and a fit that
    misses moves the target and heading onto that row (``robot.reachability.place``). ``placed`` (a
    list) receives each posture's target, yaw, pitch and whether it was moved (posture 1's also the
    sampled and derived toy place)."""
    from .posture_fit import fit_posture_heading
    from .reachability import place, reachable

    placed = [] if placed is None else placed
    placed.clear()
    write_urdfs(urdf_dir, float(p["rake_length"]), float(p["plate_width"]))
    cfg = base_config(p, urdf_dir)
    table = reachable(cfg)
    cfg, q1, bad = _posture_1(cfg, table, p, placed)
    postures = [] if q1 is None else [q1]
    if bad:
        return replace(cfg, postures=tuple(postures) + DEFAULT_POSTURES[len(postures):]), bad
    for k, (xy, region) in enumerate(zip(targets(cfg, p), regions(cfg, table[1][:, :2])), start=2):
        near = place(table, xy, p[f"yaw_{k}"], p[f"pitch_{k}"], region)
        if near is None:
            return replace(cfg, postures=tuple(postures) + DEFAULT_POSTURES[k - 1:]), [
                f"posture {k}: no reachable plate centre in its region"]
        q, miss = _fit(cfg, xy, p[f"yaw_{k}"], p[f"pitch_{k}"], p[f"swivel_{k}"], _starts() + (tuple(near[3]),))
        where = (list(xy), p[f"yaw_{k}"], p[f"pitch_{k}"], False)
        if miss > FIT_TOLERANCE:  # moved onto the nearest row of the table and fitted from it
            xy, yaw, pitch, start, _ = near
            where = (list(xy), yaw, pitch, True)
            q, miss = _fit(cfg, xy, yaw, pitch, p[f"swivel_{k}"], (tuple(start),))
        placed.append(dict(target=[round(v, 4) for v in where[0]], yaw=round(where[1], 2),
                           pitch=round(where[2], 2), moved=where[3]))
        postures.append(q)
        if miss > FIT_TOLERANCE:
            return replace(cfg, postures=tuple(postures) + DEFAULT_POSTURES[k:]), [
                f"posture {k}: the fit misses its plate-centre target by {miss:.3f} m"]
    cfg = replace(cfg, postures=tuple(postures))
    # the rake reaches behind the toy with posture 4's heading (no W3 made trivial by a short rake)
    behind = placed[0]["target"]
    q = fit_posture_heading(cfg, behind, placed[3]["yaw"], _starts() + (postures[0],), pitch_deg=placed[3]["pitch"],
                            margin=0.10)
    miss = math.dist(plate_centre(cfg, q), behind)
    if miss > FIT_TOLERANCE:
        return cfg, [f"the rake cannot reach behind the toy with posture 4's heading (misses by {miss:.3f} m)"]
    return cfg, []


def reject_reasons(cfg: WorldConfig) -> list[str]:
    """Stage 1's scene criteria (Fig. 7.2; ``scene_check.check_scene`` without the derived W6 and
    gap(4) rules, docs/world_calibration.md) that ``cfg`` fails."""
    from .scene_check import check_scene

    return check_scene(cfg, derived=False)


def derived_rules(cfg: WorldConfig) -> dict:
    """The two rules the calibration no longer imposes, as measured on ``cfg`` (recorded)."""
    from .scene_check import scene_geometry

    g = scene_geometry(cfg)
    far = cfg.toy_xy[0] + cfg.toy_size / 2
    return dict(w6=all(p["plate_x_max"] <= far for p in g[2:]), gap4_at_least_plate=g[3]["gap"] >= cfg.rake_plate[1],
                gaps=[p["gap"] for p in g], plate_centres=[p["head_xy"] for p in g])
