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
from neuroimagery.robot.world_candidate import PARAMETERS, PRESENT, base_config, rake_urdf, targets


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
    present = [(0.645, -0.135), (0.59, -0.26), (0.56, 0.08), (0.54, 0.18)]
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
