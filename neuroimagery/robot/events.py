"""What a rollout of the tool-use world reports: the six events of thesis Fig. 7.3 and the outcome.

Events (``EVENTS`` order, thesis Fig. 7.3 and Table 7.1), each named by what happens to the toy
(compass seen from above with the robot at the south edge: south = toward the robot, -x; north =
away, +x; west = the robot's left, +y; east = its right, -y):

    retrieve  the toy's centre enters the reachable area of the free left hand
              (``WorldConfig.in_reach``, ``robot.reach``)
    touch     a rake-toy contact on the toy's top face
    south, north, west, east
              the toy's centre has moved more than ``move_threshold`` from where the rollout
              started, in a direction within 45 degrees of that compass direction (docs/robot.md).

Each event, once fired, stays fired for the rest of the rollout.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from neuroimagery.core.errors import UserInputError

EVENTS = ("retrieve", "touch", "south", "north", "west", "east")


def event_index(name: str) -> int:
    """Index of event ``name`` in ``EVENTS``; a clear error for an unknown name."""
    try:
        return EVENTS.index(name)
    except ValueError:
        raise UserInputError(f"unknown event {name!r}; known events: {', '.join(EVENTS)}") from None


def watched_indices(watched) -> tuple[int, ...]:
    """Indices of the watched events: None (none), one name, or a sequence of names (a rollout
    stops when any of them fires: the robot's enabled, not yet acquired detectors, Fig. 7.5)."""
    if watched is None:
        return ()
    if isinstance(watched, str):
        return (event_index(watched),)
    return tuple(event_index(w) for w in watched)


@dataclass(frozen=True)
class Outcome:
    """What one rollout did.

    events: one bool per entry of ``EVENTS`` (fired at any time before the stop).
    fired_first: name of the first event to fire (ties broken in ``EVENTS`` order), or None.
    toy_displacement: (dx, dy) of the toy's centre between the start and the stop, metres.
    stop_step: index of the last trajectory point executed.
    final_toy_xy: the toy's centre at the stop.
    final_toy_yaw: the toy's turn about the vertical at the stop (rad in [-pi/4, pi/4): the cube
        looks the same every quarter turn).
    blew_up: the physics produced a toy state no contact can give (not finite, or faster than
        :func:`toy_fate` allows); events are then all False, so a blow-up is never counted.
    off_table: the toy fell off the table (the rollout stopped there; the events fired before
        stand).
    simulated: False when the FK filter showed the rake never came near the toy and the
        physics was skipped.
    arm_step: the trajectory point whose joints the arm holds at the stop (earlier than
        ``stop_step`` where the table stopped the arm).
    """

    events: tuple[bool, ...]
    fired_first: str | None
    toy_displacement: tuple[float, float]
    stop_step: int
    final_toy_xy: tuple[float, float]
    blew_up: bool = False
    simulated: bool = True
    min_gap: float = float("nan")  # closest the rake came to the toy's start box (m, FK; NaN if unknown)
    final_toy_yaw: float = 0.0  # the toy's turn about the vertical at the stop (rad, folded by toy_yaw_of)
    off_table: bool = False  # the toy fell off the table (the rollout stopped when it did)
    # index of the trajectory point whose joints the arm holds at the stop: the stop step, or an
    # earlier one where the table stopped the arm (docs/robot.md, the table, the grip and the arm);
    # None: the stop step
    arm_step: int | None = None

    def fired(self, name: str) -> bool:
        return self.events[event_index(name)]



def toy_fate(pos, vel, rake_speed: float, cfg) -> str:
    """Whether the toy is still in play after a control step (docs/robot.md, a toy thrown off
    the table): ``"blew_up"`` for a state no contact can give (a position or velocity that is not
    finite, or faster than ``blowup_speed_factor`` times ``rake_speed``, the fastest any rake point
    has moved so far in the rollout, plus ``blowup_speed_margin``), ``"off_table"`` once its
    centre is lower than the table's top, else ``"on_table"``."""
    if not all(map(math.isfinite, (*pos, *vel))):
        return "blew_up"
    speed = math.sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2])
    if speed > cfg.blowup_speed_factor * rake_speed + cfg.blowup_speed_margin:
        return "blew_up"
    return "off_table" if pos[2] < cfg.table_top else "on_table"


def toy_yaw_of(quaternion) -> float:
    """The turn about the vertical (rad) of a pybullet quaternion (x, y, z, w), folded into
    [-pi/4, pi/4): the toy is a uniform cube, which looks and behaves the same every quarter turn."""
    x, y, z, w = quaternion
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    quarter = math.pi / 2
    return (yaw + quarter / 2) % quarter - quarter / 2



def latch_events(now: list, fired: list, first: str | None, top: float, cfg,
                  contact_points) -> str | None:
    """Add "touch" to this step's events ``now`` from the rake-toy contacts (read only while touch
    has not fired yet), latch every event that fires into ``fired`` and return the first event."""
    if not fired[1]:
        for cp in contact_points():
            on_toy, normal = cp[6], cp[7]  # position on B (the toy), normal from B to A
            if on_toy[2] >= top - cfg.touch_tolerance and abs(normal[2]) >= cfg.touch_normal_z:
                now[1] = True
                break
    for i, f in enumerate(now):
        if f and not fired[i]:
            fired[i] = True
            if first is None:
                first = EVENTS[i]
    return first



def toy_events(x: float, y: float, dx: float, dy: float, cfg, height: float = 0.0) -> list[bool]:
    """This step's events from the toy's place ``(x, y)`` and its displacement ``(dx, dy)`` from
    the rollout's start (touch, read from the contacts, is left False; ``EVENTS`` order).

    retrieve: ``(x, y)`` in the reachable area with the toy on the table (``height``, its centre's
    height less its resting height, within ``cfg.reach_height_band``). A direction event: the
    displacement longer than ``cfg.move_threshold`` and pointing within 45 degrees of that
    direction (south -x, north +x, west +y, east -y), so one displacement fires one direction.
    """
    moved = dx * dx + dy * dy > cfg.move_threshold * cfg.move_threshold
    along_x = abs(dx) >= abs(dy)
    return [abs(height) <= cfg.reach_height_band and cfg.in_reach(x, y), False,
            moved and along_x and dx < 0, moved and along_x and dx > 0,
            moved and not along_x and dy > 0, moved and not along_x and dy < 0]
