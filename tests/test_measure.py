"""Measured stimulus properties respond as they should on synthetic shapes; the CLI prints them."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from neuroimagery.app.stimuli import main as stimuli_main
from neuroimagery.vision import make_eye, VisionConfig
from neuroimagery.vision.measure import (
    check_rules,
    format_report,
    measure_object_shapes,
    measure_set,
    near_copy_distance,
    shape_cells,
)
from neuroimagery.vision.shapes import Shape, grid_mask
from neuroimagery.vision.stimulus_sets import StimulusSet

SYNTHETIC = {
    "bar": "#/#/#/#/#/#",  # a 6:1 bar: elongated, strong axis, its own mirror image
    "square": "###/###/###",  # no axis, symmetric
    "L": "##/#./#./#.",  # chiral: its mirror image differs in a major part
    "notched": "####/####/####/##.#",  # a square with one notch off the corner: mirror differs little
    "corner": "##./..#",  # two pieces joined only at a corner
}


@pytest.fixture(scope="module")
def measured():
    s = StimulusSet("synthetic", {k: Shape(grid_mask(g), k) for k, g in SYNTHETIC.items()},
                    [90, 60, 30, 0, -30, -60], ["basic", "mirror"])
    return {m.obj: m for m in measure_object_shapes(s, make_eye(VisionConfig(size=32)))}


def test_a_long_bar_is_elongated_with_a_strong_axis_and_a_square_is_not(measured):
    bar, sq = measured["bar"], measured["square"]
    assert bar.elongation == pytest.approx(6.0, rel=0.01)  # a k:1 rectangle measures k
    assert bar.axis_min > 3.0 and bar.corners == 4 and bar.fill == pytest.approx(1.0, abs=0.01)
    assert sq.elongation == pytest.approx(1.0, abs=0.01) and sq.axis_max < 1.05
    assert sq.sides == pytest.approx(1.0, abs=0.01) and sq.fill == pytest.approx(1.0, abs=0.01)
    # both are symmetric: their mirror images and quarter turns coincide with them
    assert min(bar.mirror_iou, sq.mirror_iou, bar.symmetry_iou, sq.symmetry_iou) > 0.97


def test_mirror_iou_is_low_for_a_chiral_L_and_high_for_a_notched_square(measured):
    L, notched = measured["L"], measured["notched"]
    assert L.mirror_iou < 0.7 and L.mirror_uncovered > 0.2
    assert 0.8 < notched.mirror_iou < 0.95 and notched.mirror_uncovered < 0.1
    assert L.corners == 6 and notched.corners == 8


def test_a_corner_joined_shape_is_two_pieces(measured):
    assert measured["corner"].pieces == 2
    assert all(measured[k].pieces == 1 and measured[k].edge_components == 1
               for k in ("bar", "square", "L", "notched"))


def test_near_copies_and_cells():
    a1 = shape_cells(Shape(grid_mask("##/#./#./#.")))
    assert a1 is not None and a1.sum() == 5
    assert shape_cells(Shape(np.ones((30, 70), np.uint8))) is None  # not made of cells
    g = lambda s: shape_cells(Shape(grid_mask(s)))  # noqa: E731
    assert near_copy_distance(g("##/#./#./#."), g("##/.#/.#/.#")) == 0  # its mirror image
    assert near_copy_distance(g("##/#./#./#."), g("#./#./#./##")) == 0  # a quarter turn + mirror
    assert near_copy_distance(g("##/#./#./#."), g("##/#./#.")) == 1  # one cell shorter
    assert near_copy_distance(g("##/#./#./#."), g("#./##/#./#.")) == 2  # the foot moved


def test_rules_flag_the_shapes_that_break_them(measured):
    ms = [measured["bar"], measured["L"]]
    checks = {c.rule: c for c in check_rules("axis", ms)}
    assert not checks["chiral"].ok  # the bar is its own mirror image
    assert [v[2] for v in checks["clear main axis"].values] == [True, False]  # L: 2.75 < 3
    sq = {c.rule: c for c in check_rules("square", [measured["square"], measured["notched"]])}
    assert sq["no strong axis"].ok and sq["square-like"].ok
    assert [v[2] for v in sq["mirrors differ in small details"].values] == [True, True]
    assert [v[2] for v in sq["chiral"].values] == [False, True]
    generic = {c.rule: c for c in check_rules("generic", [measured["corner"], measured["L"]])}
    assert [v[2] for v in generic["one piece"].values] == [False, True]
    with pytest.raises(ValueError, match="training"):
        check_rules("features", ms)


def test_cli_measure_prints_properties_and_rules(tmp_path, capsys):
    assert stimuli_main(["--measure", "exp4-A", "L"]) == 0
    out = capsys.readouterr().out
    assert "exp4-A: clear main axis" in out and "mirror IoU" in out and "L: rules of every set" in out
    assert "distinct objects" in out.split("L: rules")[0] and "distinct objects" not in out.split("L: rules")[1]
    folder = tmp_path / "mine"
    folder.mkdir()
    img = np.full((120, 120, 3), 255, np.uint8)
    img[20:100, 50:70] = (0, 0, 0)
    img[20:40, 70:90] = (0, 0, 0)  # an L
    cv2.imwrite(str(folder / "ell.png"), img)
    assert stimuli_main(["--measure", str(folder), "--like", "exp4-A"]) == 0
    out = capsys.readouterr().out
    assert "clear main axis" in out and "ell" in out
    assert stimuli_main(["--measure", str(folder), "--like", "no-such-set"]) == 2
    assert capsys.readouterr().err.startswith("error:")


def test_report_formats():
    r = measure_set("exp3-a")
    md = format_report(r, markdown=True)
    assert md.splitlines()[2].startswith("| object |") and r.kind == "axis" and r.training is None
    assert measure_set("exp3-b").training == "exp3-a"
