"""Experiment 5 world contracts W5-W8 (docs/contracts.md): the geometry of the four initial
postures, measured by forward kinematics over the whole rake plate, and the movement bounds."""
from __future__ import annotations

from dataclasses import replace

import pytest

from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.scene_check import check_scene, scene_geometry

# a posture 1 whose handle passes 3.2 cm over the toy (the earlier world's), and a posture 3 whose
# plate lies beyond the toy's far face: counter-examples the checks must catch
HANDLE_OVER_TOY = (-0.67, 0.601, 0.2, 1.07, -0.467, 0.077, -0.123)
PLATE_BEYOND_TOY = (-1.087, 0.495, 0.054, 0.513, -0.0, -0.236, -0.255)


@pytest.fixture(scope="module")
def geometry():
    return scene_geometry(WorldConfig())


def test_the_default_scene_meets_every_geometric_contract():
    assert check_scene(WorldConfig()) == []


def test_w5_gaps_grow_from_posture_1_to_4(geometry):
    gaps = [g["gap"] for g in geometry]
    assert all(a < b for a, b in zip(gaps, gaps[1:])), gaps


def test_w6_no_plate_point_of_postures_3_and_4_beyond_the_toys_far_face(geometry):
    cfg = WorldConfig()
    far_face = cfg.toy_xy[0] + cfg.toy_size / 2
    for g in geometry[2:]:
        assert g["plate_x_max"] <= far_face, g


def test_w6_is_measured_over_the_whole_plate_not_only_the_toys_width():
    # this plate lies beyond the far face but off the toy's y-span: only a whole-plate check sees it
    cfg = WorldConfig()
    bad = replace(cfg, postures=(cfg.postures[0], cfg.postures[1], PLATE_BEYOND_TOY, cfg.postures[3]))
    g = scene_geometry(bad)[2]
    assert not g["behind"] and g["plate_x_max"] > cfg.toy_xy[0] + cfg.toy_size / 2
    assert any("posture 3: no point of the plate" in m for m in check_scene(bad))


def test_w7_posture_1_is_behind_the_toy_with_the_handle_beside_it(geometry):
    cfg = WorldConfig()
    g = geometry[0]
    ty, h = cfg.toy_xy[1], cfg.toy_size / 2
    assert 0.005 <= g["near_face_beyond"] <= 0.03
    assert g["plate_y_span"][0] <= ty - h and g["plate_y_span"][1] >= ty + h
    assert g["handle_over"] == 0


def test_w7_a_handle_over_the_toy_is_caught():
    cfg = WorldConfig()
    bad = replace(cfg, postures=(HANDLE_OVER_TOY,) + tuple(cfg.postures[1:]))
    assert scene_geometry(bad)[0]["handle_over"] > 0
    assert any("handle must pass beside the toy" in m for m in check_scene(bad))


def test_w8_movements_are_bounded_by_the_joint_limits_only():
    from neuroimagery.robot.movements import world_dmp

    assert world_dmp().max_goal_offset is None
