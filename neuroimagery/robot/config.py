"""Physical constants of the tool-use world (thesis ch. 7), each named, commented and range-checked.

Units: metres, seconds, kilograms, radians.  Frames: the world frame of
:mod:`neuroimagery.robot.kinematics` (x forward = north, y to the robot's left = west, z up).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

URDF_DIR = Path(__file__).resolve().parents[2] / "urdf"

# Four initial arm postures (rad, joint order of kinematics.ARM_JOINTS), fitted once by
# ``python -m neuroimagery.robot.posture_fit`` to the plate-centre targets chosen by the rule of
# docs/choices.md (the world contracts W5-W7 and the derived rules D1-D4 of docs/contracts.md, then
# the most Table 7.1 event cells; ``robot.scene_check``). Centre of the rake head's plate (x, y),
# with the toy at (0.58, -0.10):
#   1 (0.645, -0.135) behind the toy, the handle beside it (east): the plate's near face 1.5 cm beyond its north face
#   2 (0.59, -0.26)   level with the toy, on its right (east); 5.5 cm from the toy
#   3 (0.56, 0.08)    on the robot's side of the toy's far face, to its left (west); 7.5 cm
#   4 (0.54, 0.18)    far to the toy's left, the handle turned 30 degrees left: the tool-far situation; 18.1 cm
DEFAULT_POSTURES: tuple[tuple[float, ...], ...] = (
    (-0.794, 0.716, 0.283, 0.785, -0.539, 0.216, -0.255),
    (-0.307, 0.659, -0.343, 1.374, -0.431, 0.15, 0.074),
    (-1.044, 0.619, 1.151, 1.659, -0.69, -0.866, 0.342),
    (-0.959, 0.393, 1.028, 1.498, -0.622, -0.578, 0.22),
)

# The reachable area (docs/robot.md, robot.reach): the farthest x (m) the free left palm reaches at the
# height of the toy's centre, per 2-cm band of y (REACH_YS, band centres); None: not reached at that y.
REACH_YS: tuple[float, ...] = tuple(round(-0.30 + 0.02 * i, 2) for i in range(31))
REACH_FRONTIER: tuple[float | None, ...] = (
    None, None, None, 0.373, 0.391, 0.409, 0.420, 0.494, 0.504, 0.456, 0.517, 0.521, 0.525, 0.527, 0.527, 0.528,
    0.528, 0.526, 0.523, 0.522, 0.519, 0.515, 0.509, 0.503, 0.492, 0.489, 0.478, 0.463, 0.451, 0.447, 0.434)

# Hand (r_hand) -> rake transform of the fixed grasp: at the reference posture
# (-0.9, 0.35, 0, 0.9, 0, 0, 0) the handle points straight ahead and 25 degrees down.
DEFAULT_GRASP: tuple[tuple[float, ...], ...] = (
    (-0.8867, 0.1711, -0.4296, 0.0),
    (-0.1565, -0.9852, -0.0695, 0.0),
    (-0.4352, 0.0056, 0.9003, 0.0),
    (0.0, 0.0, 0.0, 1.0),
)


# where a toy thrown off the table is kept in later scenes: behind the robot, out of the eye's
# view and the rake's reach (docs/robot.md, a toy thrown off the table)
OFF_TABLE_XY = (-3.0, 0.0)


TABLE_CONTACTS = ("lift", "grip", "yield")  # the table rules (WorldConfig.table_contact; docs/robot.md)


@dataclass
class WorldConfig:
    """Everything physical about the rake / toy / table scene.

    Every field is checked in ``__post_init__``; a bad value raises ``ValueError`` naming the key.
    """

    # --- body ---------------------------------------------------------------------------------
    root_height: float = 0.80  # height of the iCub's waist (root_link) above the floor
    # the four initial arm postures (DEFAULT_POSTURES: fitted to the scene criteria, docs/robot.md)
    postures: tuple[tuple[float, ...], ...] = DEFAULT_POSTURES
    grasp: tuple[tuple[float, ...], ...] = DEFAULT_GRASP  # fixed hand -> rake transform (4x4)
    # a movement is bounded by the arm's joint limits only (the thesis states no other bound)
    # exploration: a DMP's goal noise has this share of each joint's range as its standard
    # deviation (the goal noise rule, docs/robot.md)
    goal_noise_share: float = 0.1
    rake_length: float = 0.40  # grip -> end of the handle, where the head is fixed (urdf/rake.urdf)
    # centre of the rake head's plate in the rake (grip) frame: the handle meets the plate 3.5 cm
    # above its centre (5 mm below its top edge), so the handle clears a toy the head is placed
    # behind by 2 cm (docs/robot.md, scene criteria; urdf/rake.urdf)
    rake_head_offset: tuple[float, float, float] = (0.4148, 0.0, -0.0317)
    # the head plate's box (thickness x, width y, height z), pitched -25 degrees about the rake's y
    rake_plate: tuple[float, float, float] = (0.02, 0.16, 0.08)
    # --- scene --------------------------------------------------------------------------------
    table_top: float = 0.696  # height of the table's top surface (rake head rests 8 mm above)
    # initial toy centre on the table: at least one toy width beyond the reachable area (docs/robot.md)
    toy_xy: tuple[float, float] = (0.58, -0.10)
    toy_size: float = 0.05  # side of the red toy cube (urdf/toy.urdf)
    toy_mass: float = 0.05  # kg
    rake_mass: float = 2.0  # kg; heavy enough that the 50 g toy barely deflects it between two
    #                         imposed poses (kinematic drive)
    # the hand moves the rake kinematically: its pose and velocity are imposed at every control step
    # (the table meets it by table_contact)
    table_clearance: float = 0.002  # lowest rake point kept this far above the table
    # how the table meets the rake (docs/robot.md, "The table, the grip and the arm"): "lift" = the
    # pose is lifted vertically (an arm that yields upward) | "grip" = the rake turns in the hand
    # about the grip by at most grip_pivot_max, beyond that the table stops the arm (the pose is held)
    # | "yield" = the arm (equal joint springs) takes the nearest joints that rest the rake on the
    # table, and is stopped where the joint limits allow none (robot.arm_yield)
    table_contact: str = "lift"
    grip_pivot_max: float = math.radians(10.0)  # rad the compliant grip lets the handle turn (grip only)
    friction: float = 0.5  # lateral friction of toy, rake and table
    # --- simulation ---------------------------------------------------------------------------
    physics_dt: float = 0.01  # pybullet time step (100 Hz; two steps per control step)
    # kinematic drive: no rake point travels farther than this in one physics step, the radius of
    # the handle, the thinnest colliding part (docs/robot.md, physics step criterion); a control
    # step that sweeps farther is cut into more, shorter physics steps.  None: always
    # control_dt / physics_dt steps of physics_dt
    max_substep_travel: float | None = 0.008
    control_dt: float = 0.02  # time between trajectory points (DMP integration step, 50 Hz)
    settle_steps: int = 10  # physics steps after placing the scene, before a rollout
    skip_far_steps: bool = True  # kinematic drive: skip control steps where the resting toy is out of the rake's reach
    rest_speed: float = 0.005  # m/s; a toy slower than this is at rest: control steps in which the
    #                            rake cannot reach it are skipped (kinematic drive)
    # --- events -------------------------------------------------------------------------------
    # toy displacement (m) that counts as a south/north/west/east move (its direction within 45
    # degrees of that compass direction); the reachable area (retrieve) is ``in_reach``
    move_threshold: float = 0.02
    touch_tolerance: float = 0.006  # a rake-toy contact this close to the toy's top counts as touch
    touch_normal_z: float = 0.7  # and its normal must be this vertical (|n_z|)
    # --- FK filter ----------------------------------------------------------------------------
    filter_margin: float = 0.05  # rake farther than this from the toy's box for the whole rollout:
    #                              the toy cannot have moved, skip the physics
    # --- blow-up detection --------------------------------------------------------------------
    # a blow-up is a toy faster than blowup_speed_factor x the fastest any rake point has moved so
    # far in the rollout, plus blowup_speed_margin (m/s): a speed no contact can give (docs/robot.md)
    blowup_speed_factor: float = 2.0
    blowup_speed_margin: float = 1.0
    # retrieve needs the toy on the table: its centre at most this far (m) above its resting
    # height, the band in which the reachable area was computed (robot.reach)
    reach_height_band: float = 0.01
    # --- camera -------------------------------------------------------------------------------
    image_width: int = 320
    image_height: int = 240
    camera_fov: float = 60.0  # vertical field of view, degrees
    eye_tilt: float = 0.75  # rad the eyes look down below the horizon
    eye_pan: float = -0.12  # rad the eyes look to the robot's right (negative = right)
    urdf_dir: str = field(default_factory=lambda: str(URDF_DIR))

    def __post_init__(self) -> None:
        positive = (
            "root_height", "rake_length", "table_top", "toy_size", "toy_mass", "rake_mass",
            "physics_dt", "control_dt", "move_threshold", "touch_tolerance",
            "filter_margin", "blowup_speed_factor", "blowup_speed_margin", "reach_height_band", "camera_fov", "goal_noise_share",
        )
        for key in positive:
            if not float(getattr(self, key)) > 0:
                raise ValueError(f"WorldConfig.{key} must be > 0, got {getattr(self, key)!r}")
        if self.table_contact not in TABLE_CONTACTS:
            raise ValueError(f"WorldConfig.table_contact must be one of {TABLE_CONTACTS}, got {self.table_contact!r}")
        if not 0 <= self.grip_pivot_max < math.pi / 2:
            raise ValueError(f"WorldConfig.grip_pivot_max must be in [0, pi/2), got {self.grip_pivot_max!r}")
        if not self.table_clearance >= 0:
            raise ValueError(f"WorldConfig.table_clearance must be >= 0, got {self.table_clearance}")
        if not self.rest_speed > 0:
            raise ValueError(f"WorldConfig.rest_speed must be > 0, got {self.rest_speed}")
        if not 0 <= self.friction <= 5:
            raise ValueError(f"WorldConfig.friction must be in [0, 5], got {self.friction}")
        if not 0 < self.touch_normal_z <= 1:
            raise ValueError(f"WorldConfig.touch_normal_z must be in (0, 1], got {self.touch_normal_z}")
        if self.control_dt < self.physics_dt:
            raise ValueError(
                f"WorldConfig.control_dt ({self.control_dt}) must be >= physics_dt ({self.physics_dt})"
            )
        if self.max_substep_travel is not None and not float(self.max_substep_travel) > 0:
            raise ValueError(f"WorldConfig.max_substep_travel must be > 0 or None, got {self.max_substep_travel!r}")
        if self.settle_steps < 0:
            raise ValueError(f"WorldConfig.settle_steps must be >= 0, got {self.settle_steps}")
        if len(self.postures) != 4 or any(len(p) != 7 for p in self.postures):
            raise ValueError("WorldConfig.postures must be 4 joint vectors of 7 angles")
        if len(self.grasp) != 4 or any(len(r) != 4 for r in self.grasp):
            raise ValueError("WorldConfig.grasp must be a 4x4 matrix")
        if len(self.rake_head_offset) != 3:
            raise ValueError("WorldConfig.rake_head_offset must be (x, y, z)")
        if len(self.toy_xy) != 2:
            raise ValueError("WorldConfig.toy_xy must be (x, y)")
        if self.in_reach(*self.toy_xy):
            raise ValueError(f"WorldConfig.toy_xy {self.toy_xy} lies in the reachable area: the toy must start out of reach")
        if len(self.rake_plate) != 3 or not all(v > 0 for v in self.rake_plate):
            raise ValueError("WorldConfig.rake_plate must be three positive sizes (x, y, z)")
        for key in ("image_width", "image_height"):
            if not 16 <= getattr(self, key) <= 4096:
                raise ValueError(f"WorldConfig.{key} must be in [16, 4096], got {getattr(self, key)}")
        if not Path(self.urdf_dir).is_dir():
            raise ValueError(f"WorldConfig.urdf_dir {self.urdf_dir!r} is not a folder")

    def reach_frontier_at(self, y: float) -> float:
        """The reachable area's far edge (m) at table y: the running maximum of ``REACH_FRONTIER``
        over the band of ``y`` and its two neighbours (-inf outside the bands the palm reaches)."""
        i = int(round((float(y) - REACH_YS[0]) / (REACH_YS[1] - REACH_YS[0])))
        near = [REACH_FRONTIER[j] for j in (i - 1, i, i + 1) if 0 <= j < len(REACH_FRONTIER)]
        near = [x for x in near if x is not None]
        return max(near) if near else -math.inf

    def in_reach(self, x: float, y: float) -> bool:
        """Whether a toy centred at (x, y) lies in the reachable area (the retrieve event)."""
        return float(x) <= self.reach_frontier_at(y)

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))
