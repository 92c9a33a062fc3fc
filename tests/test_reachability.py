"""The reachability table of the calibration's posture sampling (``robot.reachability``,
docs/world_calibration.md, second amendment): its rows are poses the arm reaches, it is the same
for a seed, and a sampled posture is mapped onto it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from neuroimagery.robot import reachability as R
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.world_candidate import plate_centre

DRAWS = 3000


def test_rows_rest_the_plate_on_the_table_inside_the_bounds_and_the_heading_ranges():
    cfg = WorldConfig()
    q, x = R.reachable(cfg, DRAWS, R.TABLE_SEED)
    assert 100 < len(q) < DRAWS
    lim = R._kin(cfg).joint_limits.double().numpy()
    span = lim[:, 1] - lim[:, 0]
    assert (q >= lim[:, 0] + R.MARGIN * span - 1e-9).all() and (q <= lim[:, 1] - R.MARGIN * span + 1e-9).all()
    r = R._residual(R._kin(cfg), R._corners(cfg), cfg.table_top + R.CLEARANCE, q)
    assert np.abs(r[:, 0]).max() < R.CONVERGED[0] and np.abs(r[:, 1]).max() < R.CONVERGED[1]
    assert (x[:, 2] >= -45).all() and (x[:, 2] <= 60).all() and (x[:, 3] >= 15).all() and (x[:, 3] <= 40).all()
    i = len(q) // 2
    assert math.dist(plate_centre(cfg, q[i]), x[i, :2]) < 1e-9


def test_the_table_is_the_same_for_a_seed_and_differs_for_another():
    a, b = R.base_table(DRAWS, 101), R.base_table.__wrapped__(DRAWS, 101)
    assert np.allclose(a, b)
    assert len(R.base_table.__wrapped__(DRAWS, 102)) != len(a) or not np.allclose(R.base_table.__wrapped__(DRAWS, 102), a)


def test_a_sample_far_from_the_reach_moves_onto_a_row_of_its_region_and_a_near_one_is_kept():
    cfg = WorldConfig()
    table = R.reachable(cfg, DRAWS, R.TABLE_SEED)
    x = table[1]
    region = x[:, 1] < -0.1
    xy, yaw, pitch, q, d = R.place(table, (1.5, 0.5), 10.0, 20.0, region)  # far out of reach
    i = int(np.argmin(np.abs(x[:, 0] - xy[0]) + np.abs(x[:, 1] - xy[1])))
    assert d > 1 and region[i] and np.allclose(x[i], [*xy, yaw, pitch])
    assert math.dist(plate_centre(cfg, q), xy) < 1e-9
    row = x[np.flatnonzero(region)[0]]
    near = R.place(table, (row[0] + 0.002, row[1]), row[2] + 1.0, row[3], region)
    assert near[0] == (row[0] + 0.002, row[1]) and near[1] == row[2] + 1.0 and near[4] <= 1
    assert R.place(table, (0.5, 0.0), 0.0, 20.0, np.zeros(len(x), bool)) is None


@pytest.mark.parametrize("args, says", [
    (((0.5, float("nan")), 0.0, 20.0), "finite"),
    (((0.5, 0.0), 0.0, 20.0, "short"), "region has"),
])
def test_bad_inputs_are_one_clear_error(args, says):
    table = R.reachable(WorldConfig(), DRAWS, R.TABLE_SEED)
    region = np.ones(len(table[1]), bool) if len(args) == 3 else np.ones(3, bool)
    with pytest.raises(ValueError, match=says):
        R.place(table, *args[:3], region)
