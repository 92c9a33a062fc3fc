"""Exp 5's report says why an effect has no test, speaks of its own measures in the equivalence
paragraph, and its filmstrip's title fits the figure."""
import numpy as np
import pandas as pd
import torch
from support_figures import checking_overlaps

from neuroimagery.analysis.report import Report
from neuroimagery.analysis.robots import ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE, effects
from neuroimagery.experiments.exp5.figures import filmstrip


def _rows(success_of):
    rows = []
    for robot in range(24):
        for level in (0, 1, 2):
            for strat in ("reactive", "planning"):
                rows.append({"individual": robot, "library": robot % 4, "strategy": strat, "hypothesis": "hp2",
                             "situation": "far", "level": level, "success": success_of(robot, level, strat)})
    return pd.DataFrame(rows)


def test_an_effect_without_a_test_says_why():
    df = _rows(lambda robot, level, strat: int(level > 0 and strat == "planning" and robot % 3 == 0))
    rows = effects(df, [0], [0, 1, 2])
    planning = next(r for r in rows if r["effect"].startswith("HP2 tool far: trained above untrained (planning"))
    reactive = next(r for r in rows if r["effect"].startswith("HP2 tool far: trained above untrained (reactive"))
    assert planning["value"] is None and "0 %" in planning["untested"] and "0 of 24 succeed" in planning["untested"]
    assert "every robot fails" in reactive["untested"]
    text = Report("t").effects(rows, ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE).text()
    assert "Rows without a test ('-'): HP2 tool far: trained above untrained (reactive" in text
    assert "rotation step" not in text and "RT" not in text and "z-tests" in text


def test_filmstrip_title_fits_with_one_step(tmp_path):
    pc = torch.zeros(2, 20, 20)
    film = {"strategy": "planning", "situation": "far", "hypothesis": "hp1", "level": 3, "start": pc,
            "frames": [{"imagined": pc, "real": pc, "action": "retrieve"}]}
    with checking_overlaps() as found:
        filmstrip(film, tmp_path / "film.png")
    assert found == {}, found
