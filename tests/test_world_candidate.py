"""A candidate world of the calibration (``robot.world_candidate``, ``robot.pull_paths``;
docs/world_calibration.md): the rake written at the candidate's size, the scene criteria without
the two derived rules, and the pull paths of stage 1."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from neuroimagery.robot.config import URDF_DIR, WorldConfig
from neuroimagery.robot.pull_paths import pull_paths, rake_points
from neuroimagery.robot.scene_check import check_scene
from neuroimagery.robot.world_candidate import (PARAMETERS, PRESENT, base_config, build, implied_toys, rake_urdf,
                                                targets, toy_in_ranges)


def test_the_present_rake_is_written_unchanged_and_a_longer_one_moves_its_head():
    import re

    def numbers(text):
        return [float(v) for v in re.findall(r"-?\d+\.\d+|-?\d+", text)]

    assert numbers(rake_urdf(0.40, 0.16)) == numbers((Path(URDF_DIR) / "rake.urdf").read_text())
    longer = rake_urdf(0.45, 0.18)
    assert 'length="0.4500"' in longer and 'xyz="0.4648 0 -0.0317"' in longer and 'size="0.02 0.1800 0.08"' in longer


def test_parameters_cover_the_present_world_and_its_targets_are_its_plate_centres(tmp_path):
    for name, spec in PARAMETERS.items():
        assert PRESENT[name] in spec if isinstance(spec[0], str) else spec[0] <= PRESENT[name] <= spec[1], name
    cfg = base_config(PRESENT, tmp_path)
    assert math.dist(cfg.toy_xy, WorldConfig().toy_xy) < 0.001
    assert cfg.rake_head_offset == WorldConfig().rake_head_offset
    present = [(0.59, -0.26), (0.56, 0.08), (0.54, 0.18)]  # postures 2-4 (posture 1 is placed first)
    assert all(math.dist(a, b) < 0.01 for a, b in zip(targets(cfg, PRESENT), present))


def test_without_the_derived_rules_only_w6_and_the_gap_of_the_plate_width_are_left_out():
    near4 = WorldConfig(postures=WorldConfig().postures[:3] + (WorldConfig().postures[2],))
    full, searched = check_scene(near4), check_scene(near4, derived=False)
    assert set(searched) <= set(full)
    assert {m for m in full if m not in searched} == {m for m in full if "plate's width" in m or "far face" in m}
    assert any("plate's width" in m for m in full)


def test_pull_paths_find_pulls_from_posture_1_and_measure_them_from_posture_4():
    """The present world: exploration from posture 1 drags the toy in often (Table 7.1: retrieve
    possible), and a share of those movements, performed from posture 4, passes behind the toy."""
    cfg = WorldConfig()
    r = pull_paths(cfg, 300.0, 300, 100)
    assert r["movements"] == 300 and 0.05 < r["pull_like"] < 0.5 and 0.0 < r["behind"] < 1.0
    # posture 4 moved onto posture 1: every pull-like path starts behind the toy
    same = pull_paths(replace(cfg, postures=cfg.postures[:3] + (cfg.postures[0],)), 300.0, 300, 100)
    assert same["behind"] == 1.0
    assert rake_points(cfg).shape == (101, 4)


def test_the_present_posture_1_implies_the_present_toy_and_the_ranges_are_the_written_ones():
    """Third amendment: the toy lies p1_dy from posture 1's plate centre and p1_gap short of its
    near face; the present posture 1 (near face 1.54 cm beyond the toy, plate 3.54 cm east of it)
    gives back the present toy."""
    import numpy as np

    cfg = WorldConfig()
    toy = implied_toys(cfg, np.array(cfg.postures[0]), -0.0354, 0.0154)[0]
    assert math.dist(toy, cfg.toy_xy) < 0.0006
    wider = implied_toys(cfg, np.array([cfg.postures[0]] * 2), -0.0354, 0.0254)
    assert abs(wider[1, 0] - (toy[0] - 0.01)) < 1e-6 and wider[1, 1] == toy[1]
    frontier = cfg.reach_frontier_at(-0.10)
    places = np.array([[frontier + 0.059, -0.10], [frontier + 0.12, -0.10], [frontier + 0.06, 0.05],
                       [frontier + 0.04, -0.10], [np.nan, -0.10]])
    inside, dx = toy_in_ranges(cfg, places)
    assert inside.tolist() == [True, False, False, False, False]
    assert abs(dx[0] - 0.059) < 1e-9 and abs(dx[3] - 0.04) < 1e-9


def test_posture_1_is_placed_first_and_the_toy_derived_from_it(tmp_path, monkeypatch):
    """The present world re-expressed keeps its toy within a few mm, its near face exactly p1_gap;
    a toy sampled where no plate fits behind it moves to a reachable place inside the written
    ranges; ranges no reachable plate can meet reject the candidate."""
    from neuroimagery.robot import world_candidate as wc
    from neuroimagery.robot.reachability import reachable
    from neuroimagery.robot.scene_check import scene_geometry

    placed = []
    cfg, bad = build(PRESENT, tmp_path / "present", placed)
    assert bad == [] and math.dist(cfg.toy_xy, WorldConfig().toy_xy) < 0.005
    assert abs(scene_geometry(cfg)[0]["near_face_beyond"] - PRESENT["p1_gap"]) < 0.0002
    assert placed[0]["toy_sampled"] == [0.059, -0.10] and not placed[0]["moved"]

    far = dict(PRESENT, toy_dx=0.11, toy_y=-0.20, p1_gap=0.03, p1_dy=0.05, yaw_1=60.0, pitch_1=40.0)
    base = base_config(far, tmp_path / "present")  # the same rake
    table = reachable(base)
    placed = []
    moved, q1, bad = wc._posture_1(base, table, far, placed)
    assert bad == [] and q1 is not None
    dx, y = placed[0]["toy_derived"]
    assert 0.05 <= dx <= 0.11 and -0.20 <= y <= 0.0 and moved.toy_xy != base.toy_xy
    assert abs(scene_geometry(replace(moved, postures=(q1,) + moved.postures[1:]))[0]["near_face_beyond"] - 0.03) < 2e-4

    monkeypatch.setitem(wc.PARAMETERS, "toy_dx", (0.5, 0.6))
    assert wc._posture_1(base, table, far, [])[2] == ["posture 1: no reachable plate with the toy in its ranges"]
