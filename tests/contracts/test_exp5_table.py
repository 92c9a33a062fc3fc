"""Experiment 5 world contracts W1-W4 (docs/contracts.md): Table 7.1's event and skill cells at the
1 % threshold, a pull alone from posture 4 under 5 % of the libraries, a move-then-pull route for
most of them. The full measurements are slow; the default suite runs a small smoke version.

The full W1, W2 and W3 tests are strict xfails: the world misses them (docs/robot.md, "Table 7.1,
measured"); they are kept so that the suite says so, and a world that meets one turns it into a
failure to be promoted.
"""
from __future__ import annotations

import pytest

from neuroimagery.robot.babble import POSSIBLE_RATE, THESIS_EVENTS, measure


def test_w1_smoke_retrieval_only_from_the_tool_behind_situation():
    t = measure(100, seeds=1)
    assert t["possible_rate"] == POSSIBLE_RATE == 0.01
    rates = {k: t[k]["rates"] for k in THESIS_EVENTS}
    assert rates["posture-1"][0] > POSSIBLE_RATE  # retrieve possible from posture 1 ...
    assert rates["posture-3"][0] <= POSSIBLE_RATE and rates["posture-4"][0] <= POSSIBLE_RATE  # ... not from 3, 4
    assert all(0 <= r <= 1 for v in rates.values() for r in v)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the world gives 19 of 24 event cells at W1's size (docs/robot.md)")
def test_w1_table_7_1_events_at_least_20_of_24():
    t = measure(10000, seeds=10)  # W1's sample size, 100,000 movements per posture (docs/contracts.md)
    assert t["agreement"][str(POSSIBLE_RATE)] >= 20


@pytest.fixture(scope="module")
def libraries():
    from neuroimagery.experiments.exp5.world import _one_library, summarise

    # W2-W4's sample (docs/contracts.md): 16 libraries on each of the seeds 0-4
    return summarise([_one_library(seed, i) for seed in range(5) for i in range(16)])


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the world gives 17 of 24 skill cells over 80 libraries (docs/robot.md)")
def test_w2_table_7_1_skills_at_least_20_of_24(libraries):
    assert libraries["skill_agreement"][str(POSSIBLE_RATE)] >= 20


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="a pull alone retrieves from posture 4 in 18 of 80 libraries (docs/robot.md)")
def test_w3_a_pull_alone_retrieves_from_posture_4_for_under_5_percent(libraries):
    assert libraries["with_pull"] > 0 and libraries["pull_alone_share"] < 0.05


@pytest.mark.slow
def test_w4_a_move_then_pull_route_from_posture_4_for_most_libraries(libraries):
    assert libraries["move_then_pull_share"] > 0.5
