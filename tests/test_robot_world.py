"""The rake/toy/table world: events from physics, FK filter, errors, camera."""
import numpy as np
import pytest
import torch

from neuroimagery.core.errors import UserInputError
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.events import toy_events
from neuroimagery.robot.movements import MovementConfig, goal_noise, random_primitives, trajectories, world_dmp
from neuroimagery.robot.scene_check import check_scene, scene_geometry
from neuroimagery.robot.events import EVENTS
from neuroimagery.robot.world import ToolWorld, toy_yaw_of


@pytest.fixture(scope="module")
def world():
    with ToolWorld() as w:
        yield w


def _line(world, posture, head_target_delta, T=150):
    """Joint trajectory from the posture whose rake head moves by ``head_target_delta`` (small IK)."""
    return _line_from(world, world.initial_posture(posture), head_target_delta, T)


def _path(world, posture, deltas, T=60):
    """Joint trajectory through head waypoints: each of ``deltas`` moves the head on from the last."""
    q = world.initial_posture(posture)
    parts = []
    for d in deltas:
        seg = _line_from(world, q, d, T)
        parts.append(seg[0])
        q = seg[0, -1]
    return torch.cat(parts).unsqueeze(0)


def _line_from(world, q0, delta, T):
    """Joint trajectory from joint angles ``q0`` whose rake head moves by ``delta`` (small IK)."""
    start = world.kin.rake_head_position(q0)
    target = start + torch.tensor(delta)
    q = q0.clone().requires_grad_(True)
    opt = torch.optim.Adam([q], lr=0.01)
    for _ in range(300):
        opt.zero_grad()
        ((world.kin.rake_head_position(world.kin.clamp(q)) - target) ** 2).sum().backward()
        opt.step()
    q1 = world.kin.clamp(q.detach())
    s = torch.linspace(0, 1, T).unsqueeze(1)
    s = 3 * s**2 - 2 * s**3
    return (q0 + s * (q1 - q0)).unsqueeze(0)


def test_config_errors_name_the_key():
    with pytest.raises(ValueError, match="toy_mass"):
        WorldConfig(toy_mass=-1.0)
    with pytest.raises(ValueError, match="toy_xy"):
        WorldConfig(toy_xy=(0.30, -0.10))  # inside the reachable area: the toy must start out of reach
    with pytest.raises(ValueError, match="table_contact"):
        WorldConfig(table_contact="glue")
    with pytest.raises(ValueError, match="grip_pivot_max"):
        WorldConfig(grip_pivot_max=-0.1)


def test_scene_meets_its_written_criteria():
    """docs/robot.md, scene criteria: all met by the default scene, and a posture moved onto the
    toy, a handle lowered onto it or a posture 4 brought near are each caught."""
    assert check_scene() == []
    g = scene_geometry()
    assert g[0]["behind"] and all(not p["behind"] for p in g[1:])
    assert [p["gap"] for p in g] == sorted(p["gap"] for p in g) and g[3]["gap"] >= 0.16
    swapped = WorldConfig(postures=(WorldConfig().postures[3],) + WorldConfig().postures[1:])
    assert any("posture 1" in m for m in check_scene(swapped))
    near4 = WorldConfig(postures=WorldConfig().postures[:3] + (WorldConfig().postures[1],))
    assert any("gap" in m for m in check_scene(near4))


def test_reachable_area_is_the_free_hands_reach():
    """retrieve = the toy's centre within the left palm's reach at table height (robot.reach);
    the toy starts beyond it by a toy width; a point past the frontier is out of reach."""
    cfg = WorldConfig()
    y = cfg.toy_xy[1]
    edge = cfg.reach_frontier_at(y)
    assert 0.3 < edge < cfg.toy_xy[0] - cfg.toy_size
    assert cfg.in_reach(edge - 0.001, y) and not cfg.in_reach(edge + 0.001, y)
    assert not cfg.in_reach(*cfg.toy_xy)
    assert not cfg.in_reach(0.2, -0.9)  # far to the right: no band of the frontier


def test_direction_events_take_one_direction_per_displacement():
    cfg = WorldConfig()
    far = cfg.toy_xy[0]
    # (retrieve, touch, south, north, west, east) for displacements from the start
    assert toy_events(far, 0.0, -0.03, -0.02, cfg) == [False, False, True, False, False, False]  # diagonal: south
    assert toy_events(far, 0.0, 0.01, 0.025, cfg) == [False, False, False, False, True, False]
    assert toy_events(far, 0.0, 0.005, -0.03, cfg) == [False, False, False, False, False, True]
    assert toy_events(far, 0.0, 0.03, 0.0, cfg) == [False, False, False, True, False, False]
    assert toy_events(far, 0.0, -0.015, -0.01, cfg) == [False] * 6  # 1.8 cm: below the threshold
    assert toy_events(0.3, cfg.toy_xy[1], -0.28, 0.0, cfg)[0]  # in reach
    # retrieve needs the toy on the table: not flying over the area, not falling past its edge
    assert toy_events(0.3, cfg.toy_xy[1], -0.28, 0.0, cfg, height=0.009)[0]
    assert not toy_events(0.3, cfg.toy_xy[1], -0.28, 0.0, cfg, height=0.02)[0]
    assert not toy_events(0.3, cfg.toy_xy[1], -0.28, 0.0, cfg, height=-0.02)[0]


def test_thesis_events_fire_from_their_postures(world):
    """Table 7.1: retrieve (with south) from posture 1 by a pull; west from posture 2 by a sweep;
    touch from posture 2 by lifting the head over the toy and lowering it onto its top."""
    pull = world.rollout(_path(world, 1, [(-0.22, 0.0, 0.0)]), 1, None)[0]
    assert pull.fired("retrieve") and pull.fired("south") and not pull.fired("north"), pull
    sweep = world.rollout(_path(world, 2, [(0.0, 0.16, 0.0)]), 2, None)[0]
    assert sweep.fired("west") and not sweep.fired("east") and not sweep.fired("retrieve"), sweep
    toy_y = world.cfg.toy_xy[1]
    head = world.kin.rake_head_position(world.initial_posture(2))
    over = (0.0, toy_y - float(head[1]), 0.10)
    touch = world.rollout(_path(world, 2, [over, (0.0, 0.0, -0.09)]), 2, "touch")[0]
    assert touch.fired("touch") and not touch.fired("retrieve"), touch


def test_scene_is_at_rest(world):
    for k in range(1, 5):
        out = world.rollout(world.initial_posture(k).repeat(1, 50, 1), k, None, use_filter=False)[0]
        assert not any(out.events), (k, out)
        assert np.hypot(*out.toy_displacement) < 0.005


def test_pulling_from_posture_1_moves_toy_south_and_stops_on_watched(world):
    traj = _line(world, 1, (-0.16, 0.0, 0.0))
    full = world.rollout(traj, 1, None)[0]
    assert full.fired("south") and full.fired("retrieve") and not full.blew_up
    assert full.toy_displacement[0] < -0.08
    assert not full.fired("north")
    stopped = world.rollout(traj, 1, "south")[0]
    assert stopped.fired("south") and stopped.fired_first in EVENTS
    assert stopped.stop_step < full.stop_step
    assert stopped.events[EVENTS.index("retrieve")] is False  # stopped before the toy got in reach


def test_direction_events_agree_with_displacement(world):
    thr = world.cfg.move_threshold
    for k, delta in ((1, (-0.12, 0.05, 0.0)), (1, (-0.16, 0.0, 0.0))):
        out = world.rollout(_line(world, k, delta), k, None)[0]
        dx, dy = out.toy_displacement
        assert np.hypot(dx, dy) > thr  # the sweep did push the toy
        # these pushes keep their direction, so the final displacement's sector has fired
        sector = ("south" if dx < 0 else "north") if abs(dx) >= abs(dy) else ("west" if dy > 0 else "east")
        assert out.fired(sector), (sector, out)


def test_fk_filter_and_skipped_steps_never_change_an_outcome(world):
    """Reference: the same world simulating every control step of every rollout."""
    dmp = world_dmp()
    gen = torch.Generator().manual_seed(5)
    cfg = MovementConfig()
    with ToolWorld(WorldConfig(skip_far_steps=False)) as full:
        for k in (1, 2, 4):
            theta = goal_noise(world, dmp, random_primitives(world, dmp, 16, cfg, gen), gen)
            traj = trajectories(world, dmp, theta, world.initial_posture(k), cfg)
            fast = world.rollout(traj, k, None, use_filter=True)
            slow = full.rollout(traj, k, None, use_filter=False)
            assert any(a.simulated for a in fast)
            for a, b in zip(fast, slow):
                assert a.events == b.events, (k, a, b)
                assert np.allclose(a.toy_displacement, b.toy_displacement, atol=2e-3), (k, a, b)
                if not a.simulated:
                    assert np.hypot(*b.toy_displacement) < 1e-3


def test_the_grip_holds_the_arm_only_beyond_its_bound(world):
    """Under the option ``table_contact="grip"`` the grip turns the rake in the hand, and the table
    stops the arm only where the turn would exceed ``grip_pivot_max``."""
    # pulls from posture 1: level, to the side, pressing the head 4 cm into the table (the grip
    # turns, the arm is not stopped) and 8 cm (beyond the grip's bound: the table stops the arm)
    pulls = ((-0.16, 0.0, 0.0), (-0.12, 0.05, 0.0), (-0.16, 0.0, -0.04), (-0.16, 0.0, -0.08))
    # straight sweeps: east from posture 3 (level with the toy, on its left), west from posture 2
    sweeps = ((3, (0.0, -0.16, 0.0)), (2, (0.0, 0.16, 0.0)))
    with ToolWorld(WorldConfig(table_contact="grip")) as kin:
        held = []
        for k, delta in [(1, d) for d in pulls] + list(sweeps):
            traj = _line(world, k, delta)
            held.append(bool((kin._plan(traj.numpy())["arm_step"] != np.arange(traj.shape[1])).any()))
        assert held == [False, False, False, True, False, False]  # the moves cover both parts of the rule


def test_toy_turn_is_placed_read_back_and_reported(world):
    """A scene can start with the toy turned; its turn is read back folded to a quarter turn (a
    uniform cube), and a rollout reports the turn it leaves."""
    quarter = np.pi / 2
    for yaw in (0.3, -0.6, 0.3 + quarter, -0.3 - 2 * quarter):
        q = (0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2))
        assert np.isclose(toy_yaw_of(q), (yaw + quarter / 2) % quarter - quarter / 2), yaw
    world.reset(4, toy_xy=(0.57, 0.01), toy_yaw=0.3)
    assert np.isclose(world.toy_yaw(), 0.3, atol=0.005) and np.allclose(world.toy_xy(), (0.57, 0.01), atol=0.002)
    turned = world.observe(posture=4, toy_xy=(0.57, 0.01), toy_yaw=0.6)["toy"]
    square = world.observe(posture=4, toy_xy=(0.57, 0.01))["toy"]
    assert int((turned != square).sum()) > 20  # the eye sees the turn
    # a sweep west from posture 2 turns the cube it pushes; the outcome reports the world's turn
    out = world.rollout(_line(world, 2, (0.0, 0.16, 0.0)), 2, None)[0]
    assert np.isclose(out.final_toy_yaw, world.toy_yaw())
    assert abs(out.final_toy_yaw) > 0.02, out


def test_quaternion_helpers_match_scipy():
    from scipy.spatial.transform import Rotation

    from neuroimagery.robot.rake_pose import quat_from_matrix as _quat_from_matrix, rotvec_between as _rotvec_between

    r0, r1 = Rotation.random(500, random_state=0), Rotation.random(500, random_state=1)
    q = _quat_from_matrix(r0.as_matrix())
    assert np.allclose(np.abs((q * r0.as_quat()).sum(-1)), 1.0, atol=1e-12)  # same rotation (q ~ -q)
    assert np.allclose(_rotvec_between(r0.as_quat(), r1.as_quat()), (r1 * r0.inv()).as_rotvec(), atol=1e-9)


def test_rake_never_goes_through_the_table(world):
    q0 = world.initial_posture(1)
    down = q0.clone()
    down[0] += 0.4  # shoulder pitch: swing the arm down, the head would sink into the table
    traj = (q0 + torch.linspace(0, 1, 30)[:, None] * (down - q0))[None]
    cmd = world.kin.rake_pose_np(traj.numpy())
    plan = world._plan(traj.numpy())
    low = (plan["pts"][..., 2] - world._point_radius).min(-1)
    assert low.min() >= world.cfg.table_top + world.cfg.table_clearance - 1e-9
    # the default rule (table_contact="lift"): the pose lifted vertically, its turn kept, never held
    assert world.cfg.table_contact == "lift"
    assert (plan["arm_step"] == np.arange(30)).all() and np.allclose(plan["poses"][..., :3, :3], cmd[..., :3, :3])
    assert np.allclose(plan["poses"][..., :2, 3], cmd[..., :2, 3])
    assert (plan["poses"][0, -1, 2, 3] - cmd[0, -1, 2, 3]) > 0.1  # the grip 10+ cm above the commanded hand
    # the option table_contact="grip": the rake stays in the hand, its grip where the arm's held
    # joints put the hand, turned in the hand by at most the grip's bound; the arm goes on until the
    # bound is spent, then is held
    with ToolWorld(WorldConfig(table_contact="grip")) as gripped:
        plan = gripped._plan(traj.numpy())
        low = (plan["pts"][..., 2] - gripped._point_radius).min(-1)
        assert low.min() >= gripped.cfg.table_top + gripped.cfg.table_clearance - 1e-9
        arm = plan["arm_step"][0]
        first_held = int(np.flatnonzero(arm != np.arange(30))[0])
        assert 2 <= first_held < 29 and (arm[first_held:] == first_held - 1).all() and (arm[:first_held] == np.arange(first_held)).all()
        grip, hand = plan["poses"][0, :, :3, 3], cmd[0, arm, :3, 3]
        assert np.abs(grip - hand).max() < 1e-6
        R, Rc = plan["poses"][0, :, :3, :3], cmd[0, arm, :3, :3]
        turn = np.arccos(np.clip((np.einsum("tji,tji->t", R, Rc) - 1) / 2, -1, 1))
        assert turn.max() <= gripped.cfg.grip_pivot_max + 1e-3 and turn[first_held - 1] > 0.8 * gripped.cfg.grip_pivot_max


def test_errors(world):
    q = world.initial_posture(1).repeat(1, 10, 1)
    with pytest.raises(UserInputError, match="unknown event"):
        world.rollout(q, 1, "sideways")
    with pytest.raises(UserInputError, match="posture"):
        world.rollout(q, 5, None)
    bad = q.clone()
    bad[0, 5, 3] = 2.5
    with pytest.raises(ValueError, match="outside the URDF limits.*r_elbow"):
        world.rollout(bad, 1, None)
    bad[0, 5, 3] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        world.rollout(bad, 1, None)


def test_blow_up_is_reported_not_counted():
    cfg = WorldConfig(blowup_speed_factor=1e-6, blowup_speed_margin=1e-4)  # any push is now absurd
    with ToolWorld(cfg) as w:
        out = w.rollout(_line(w, 1, (-0.16, 0.0, 0.0)), 1, None)[0]
    assert out.blew_up and not any(out.events) and out.fired_first is None
    with ToolWorld() as w:  # the same pull under the default rule is a plain retrieval
        out = w.rollout(_line(w, 1, (-0.16, 0.0, 0.0)), 1, None)[0]
    assert not out.blew_up and out.fired("retrieve") and out.fired("south")


def test_observe_masks(world):
    obs = world.observe(posture=1)
    assert obs["image"].shape == (240, 320, 3) and obs["image"].dtype == np.uint8
    assert obs["toy"].shape == (240, 320) and obs["rake"].shape == (240, 320)
    assert obs["toy"].sum() > 50 and obs["rake"].sum() > 50
    assert (obs["toy"] * obs["rake"]).sum() == 0
    # the toy's blob moves in the image when the toy moves
    moved = world.observe(posture=1, toy_xy=(0.50, -0.10))
    cy = lambda m: (m.sum(1) * torch.arange(240)).sum() / m.sum()
    assert cy(moved["toy"]) > cy(obs["toy"]) + 3  # nearer the robot = lower in the image


def test_colour_masks_apply_the_thresholds_exactly():
    from neuroimagery.robot.eye import colour_masks

    px = np.array([[[61, 30, 30], [60, 10, 10], [100, 50, 10], [101, 50, 50], [255, 255, 255]],
                   [[30, 61, 30], [10, 60, 10], [50, 100, 10], [50, 101, 50], [0, 0, 0]]], dtype=np.uint8)
    toy, rake = colour_masks(px)
    assert toy.dtype == rake.dtype == torch.float32
    assert toy.tolist() == [[1, 0, 0, 1, 0], [0, 0, 0, 0, 0]]
    assert rake.tolist() == [[0, 0, 0, 0, 0], [1, 0, 0, 1, 0]]


def test_babble_keeps_each_piece_and_gives_the_same_table_with_workers(tmp_path, monkeypatch):
    """Each posture and seed's counts are kept in ``DIR/counts/`` and reused by a rerun; worker
    processes (``--jobs 2``) give the same table as one process."""
    from neuroimagery.robot import babble

    one, two = tmp_path / "one", tmp_path / "two"
    assert babble.main(["--rollouts", "10", "--seeds", "2", "--out", str(one)]) == 0
    assert babble.main(["--rollouts", "10", "--seeds", "2", "--jobs", "2", "--out", str(two)]) == 0
    first = (one / "table_7_1.json").read_text()
    assert (two / "table_7_1.json").read_text() == first
    assert len(list((one / "counts").glob("posture*_seed*.json"))) == 8

    def no_rollouts(*a, **k):
        raise AssertionError("a kept piece was computed again")

    monkeypatch.setattr(babble, "babble_counts", no_rollouts)
    (one / "table_7_1.json").unlink()
    assert babble.main(["--rollouts", "10", "--seeds", "2", "--out", str(one)]) == 0
    assert (one / "table_7_1.json").read_text() == first
    with pytest.raises(AssertionError, match="computed again"):  # other settings: computed again
        babble.main(["--rollouts", "11", "--seeds", "2", "--out", str(one)])


def test_babble_writes_rates_intervals_and_the_agreement_curve(tmp_path):
    """``python -m neuroimagery.robot.babble``: table_7_1.json keeps ``events`` and ``rates`` and adds
    ``rates_ci95`` and the agreement at several thresholds; a bad count is one error line."""
    import json

    from neuroimagery.robot import babble

    assert babble.main(["--rollouts", "25", "--seeds", "1", "--out", str(tmp_path)]) == 0
    t = json.loads((tmp_path / "table_7_1.json").read_text())
    for k in ("posture-1", "posture-2", "posture-3", "posture-4"):
        row = t[k]
        assert row["rollouts"] == 25 and len(row["events"]) == len(row["rates"]) == len(row["rates_ci95"]) == 6
        assert all(lo <= r <= hi for r, (lo, hi) in zip(row["rates"], row["rates_ci95"]))
        assert row["events"] == [int(r > babble.POSSIBLE_RATE) for r in row["rates"]]
    assert set(t["agreement"]) == {str(x) for x in babble.CURVE_THRESHOLDS}
    assert t["posture-1"]["rates"][EVENTS.index("south")] > 0  # random pulls from behind the toy move it south
    assert babble.main(["--rollouts", "0", "--out", str(tmp_path)]) == 2
    assert babble.wilson(0, 100)[0] == 0.0 and 0.0 < babble.wilson(0, 100)[1] < 0.05
