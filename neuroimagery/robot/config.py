"""Physical constants of the tool-use world (thesis ch. 7), each named, commented and range-checked.

Units: metres, seconds, kilograms, radians.  Frames: the world frame of
:mod:`neuroimagery.robot.kinematics` (x forward = north, y to the robot's left = west, z up).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

from neuroimagery.motor.dmp import MAX_GOAL_OFFSET_RAD

URDF_DIR = Path(__file__).resolve().parents[2] / "urdf"

# Four initial arm postures (rad, joint order of kinematics.ARM_JOINTS).  Found once by a small
# inverse-kinematics fit of the rake head's centre to a point on the table, the head plate upright
# and spanning left-right and every joint at least 12 % of its range from a limit (docs/robot.md).
# Rake head centre (x, y) with the toy at (0.56, -0.10); the plate is 16 cm wide (+-8 cm in y):
#   1 (0.62, -0.10)  just beyond the toy (north of it): a pull toward the robot brings it in
#   2 (0.56, -0.245) level with the toy, on its right (east); the plate's end 4 cm from the toy
#   3 (0.64, -0.30)  beyond the toy and to its right; the plate's end 10 cm from the toy
#   4 (0.60, -0.38)  far to the toy's right; the plate's end 17 cm from the toy
#     (WorldConfig.posture_4 = "right", the default).
#   4 (0.525, -0.43) posture_4 = "far": far to the toy's right and 3.5 cm nearer the robot, the
#     plate's end 22.5 cm from the toy.  Chosen so that no learnt pull of the 60 libraries of an
#     Exp 5 run retrieves the toy from it in one movement while the events random babbling fires
#     from "right" still fire; not the default, because with it the tool-far success no longer
#     rises with the number of skills (docs/robot.md, docs/exp5.md).
POSTURE_4: dict[str, tuple[float, ...]] = {
    "far": (-0.083, 0.683, -0.361, 1.462, -0.372, -0.331, 0.035),
    "right": (-0.599, 0.543, -0.165, 0.971, -0.125, -0.260, -0.202),
}
DEFAULT_POSTURE_4 = "right"
POSTURES_1_3: tuple[tuple[float, ...], ...] = (
    (-0.464, 0.561, 0.119, 1.191, -0.456, 0.067, -0.188),
    (-0.047, 0.546, -0.394, 1.594, -0.468, 0.075, 0.017),
    (-0.850, 0.499, 0.047, 0.732, -0.129, -0.263, -0.239),
)
DEFAULT_POSTURES: tuple[tuple[float, ...], ...] = POSTURES_1_3 + (POSTURE_4[DEFAULT_POSTURE_4],)

# Hand (r_hand) -> rake transform of the fixed grasp: at the reference posture
# (-0.9, 0.35, 0, 0.9, 0, 0, 0) the handle points straight ahead and 25 degrees down.
DEFAULT_GRASP: tuple[tuple[float, ...], ...] = (
    (-0.8867, 0.1711, -0.4296, 0.0),
    (-0.1565, -0.9852, -0.0695, 0.0),
    (-0.4352, 0.0056, 0.9003, 0.0),
    (0.0, 0.0, 0.0, 1.0),
)


@dataclass
class WorldConfig:
    """Everything physical about the rake / toy / table scene.

    Every field is checked in ``__post_init__``; a bad value raises ``ValueError`` naming the key.
    """

    # --- body ---------------------------------------------------------------------------------
    root_height: float = 0.80  # height of the iCub's waist (root_link) above the floor
    # which joint vector is posture 4 (the tool-far situation): "far" | "right" (the previous one)
    posture_4: str = DEFAULT_POSTURE_4
    # the four initial arm postures; None = POSTURES_1_3 + POSTURE_4[posture_4]
    postures: tuple[tuple[float, ...], ...] | None = None
    grasp: tuple[tuple[float, ...], ...] = DEFAULT_GRASP  # fixed hand -> rake transform (4x4)
    # reach of one movement: a DMP's goal lies within this many rad of its start posture in every
    # joint (the bound ``motor.dmp.DMP`` applies by default; babbling and PI^BB use this key)
    max_goal_offset_rad: float = MAX_GOAL_OFFSET_RAD
    rake_length: float = 0.40  # grip -> end of the handle, where the head is fixed (urdf/rake.urdf)
    # centre of the rake head's plate in the rake (grip) frame: the handle meets the plate 2 cm
    # above its centre, so the handle clears a toy the head is placed behind (urdf/rake.urdf)
    rake_head_offset: tuple[float, float, float] = (0.4085, 0.0, -0.0181)
    # --- scene --------------------------------------------------------------------------------
    table_top: float = 0.696  # height of the table's top surface (rake head rests 8 mm above)
    toy_xy: tuple[float, float] = (0.56, -0.10)  # initial toy centre on the table
    toy_size: float = 0.05  # side of the red toy cube (urdf/toy.urdf)
    toy_mass: float = 0.05  # kg
    rake_mass: float = 2.0  # kg; heavy enough that the 50 g toy barely deflects it between two
    #                         imposed poses (kinematic drive)
    rake_max_force: float = 200.0  # N, strength of the constraint (only with rake_drive="constraint")
    # how the hand moves the rake: "kinematic" imposes the rake's pose and velocity at every control
    # step (the table stops it by lifting the pose); "constraint" drags it with a fixed constraint of
    # force rake_max_force (slower; kept as a reference)
    rake_drive: str = "kinematic"
    table_clearance: float = 0.002  # kinematic drive: lowest rake point kept this far above the table
    friction: float = 0.5  # lateral friction of toy, rake and table
    # --- simulation ---------------------------------------------------------------------------
    physics_dt: float = 0.01  # pybullet time step (100 Hz; two steps per control step)
    control_dt: float = 0.02  # time between trajectory points (DMP integration step, 50 Hz)
    settle_steps: int = 10  # physics steps after placing the scene, before a rollout
    skip_far_steps: bool = True  # kinematic drive: skip control steps where the resting toy is out of the rake's reach
    rest_speed: float = 0.005  # m/s; a toy slower than this is at rest: control steps in which the
    #                            rake cannot reach it are skipped (kinematic drive)
    # --- events -------------------------------------------------------------------------------
    move_threshold: float = 0.02  # toy displacement (m) that counts as a south/north/west/east move
    retrieve_x: float = 0.48  # reachable area: toy centre closer than this to the robot (x < ...)
    touch_tolerance: float = 0.006  # a rake-toy contact this close to the toy's top counts as touch
    touch_normal_z: float = 0.7  # and its normal must be this vertical (|n_z|)
    # --- FK filter ----------------------------------------------------------------------------
    filter_margin: float = 0.05  # rake farther than this from the toy's box for the whole rollout:
    #                              the toy cannot have moved, skip the physics
    # --- blow-up detection --------------------------------------------------------------------
    max_toy_speed: float = 5.0  # m/s; faster than this is a physics blow-up, not an event
    max_toy_height: float = 0.30  # m above the table top; higher is a blow-up
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
            "rake_max_force", "physics_dt", "control_dt", "move_threshold", "touch_tolerance",
            "filter_margin", "max_toy_speed", "max_toy_height", "camera_fov", "max_goal_offset_rad",
        )
        for key in positive:
            if not float(getattr(self, key)) > 0:
                raise ValueError(f"WorldConfig.{key} must be > 0, got {getattr(self, key)!r}")
        if self.rake_drive not in ("kinematic", "constraint"):
            raise ValueError(f"WorldConfig.rake_drive must be 'kinematic' or 'constraint', got {self.rake_drive!r}")
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
        if self.settle_steps < 0:
            raise ValueError(f"WorldConfig.settle_steps must be >= 0, got {self.settle_steps}")
        if self.posture_4 not in POSTURE_4:
            raise ValueError(f"WorldConfig.posture_4 must be one of {sorted(POSTURE_4)}, got {self.posture_4!r}")
        if self.postures is None:
            self.postures = POSTURES_1_3 + (POSTURE_4[self.posture_4],)
        if len(self.postures) != 4 or any(len(p) != 7 for p in self.postures):
            raise ValueError("WorldConfig.postures must be 4 joint vectors of 7 angles")
        if len(self.grasp) != 4 or any(len(r) != 4 for r in self.grasp):
            raise ValueError("WorldConfig.grasp must be a 4x4 matrix")
        if len(self.rake_head_offset) != 3:
            raise ValueError("WorldConfig.rake_head_offset must be (x, y, z)")
        if len(self.toy_xy) != 2:
            raise ValueError("WorldConfig.toy_xy must be (x, y)")
        if not self.retrieve_x < self.toy_xy[0]:
            raise ValueError(
                f"WorldConfig.retrieve_x ({self.retrieve_x}) must be nearer than the toy's start "
                f"x ({self.toy_xy[0]}): the toy starts out of reach"
            )
        for key in ("image_width", "image_height"):
            if not 16 <= getattr(self, key) <= 4096:
                raise ValueError(f"WorldConfig.{key} must be in [16, 4096], got {getattr(self, key)}")
        if not Path(self.urdf_dir).is_dir():
            raise ValueError(f"WorldConfig.urdf_dir {self.urdf_dir!r} is not a folder")

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))
