"""The tool-use world of thesis ch. 7: a table, a red toy and a green rake held by the iCub.

Only the rake, the toy and the table take part in the physics.  The iCub's body is represented by
its kinematics: the right arm's joint trajectory goes through batched forward kinematics
(:class:`~neuroimagery.robot.kinematics.ArmKinematics`), the fixed grasp gives the pose the rake
must have at every control step, and a strong fixed constraint drags the (dynamic) rake body to that
pose.  pybullet then resolves rake-toy-table contact; the toy moves only when pushed.

Compass convention (seen from above, robot at the south edge looking north):
    south = toward the robot (-x), north = away from it (+x),
    west  = the robot's left (+y),  east  = the robot's right (-y).

Events (``EVENTS`` order, thesis Fig. 7.3):
    retrieve  the toy's centre enters the reachable area ``x < WorldConfig.retrieve_x``
    touch     a rake-toy contact on the toy's top face (contact point within
              ``touch_tolerance`` of the top, normal with ``|n_z| >= touch_normal_z``)
    south, north, west, east
              the toy's centre has moved more than ``move_threshold`` in that direction from
              where the rollout started.
Each event, once fired, stays fired for the rest of the rollout.  A rollout stops at the first
control step where the watched event has fired (the thesis stops the arm as soon as the event
of interest happens).
"""
from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from neuroimagery.errors import UserInputError
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.kinematics import ArmKinematics

EVENTS = ("retrieve", "touch", "south", "north", "west", "east")


def event_index(name: str) -> int:
    """Index of event ``name`` in ``EVENTS``; a clear error for an unknown name."""
    try:
        return EVENTS.index(name)
    except ValueError:
        raise UserInputError(f"unknown event {name!r}; known events: {', '.join(EVENTS)}") from None


@dataclass(frozen=True)
class Outcome:
    """What one rollout did.

    events: one bool per entry of ``EVENTS`` (fired at any time before the stop).
    fired_first: name of the first event to fire (ties broken in ``EVENTS`` order), or None.
    toy_displacement: (dx, dy) of the toy's centre between the start and the stop, metres.
    stop_step: index of the last trajectory point executed.
    final_toy_xy: the toy's centre at the stop.
    blew_up: the physics produced an absurd toy state (too fast or flying); events are then all
        False, so a blow-up is never counted as an event.
    simulated: False when the FK filter showed the rake never came near the toy and the
        physics was skipped.
    """

    events: tuple[bool, ...]
    fired_first: str | None
    toy_displacement: tuple[float, float]
    stop_step: int
    final_toy_xy: tuple[float, float]
    blew_up: bool = False
    simulated: bool = True

    def fired(self, name: str) -> bool:
        return self.events[event_index(name)]


@contextlib.contextmanager
def _quiet():
    """Silence pybullet's C-level prints (URDF loading chatter) on stdout/stderr."""
    try:
        fds = [os.dup(1), os.dup(2)]
    except OSError:  # no real file descriptors (e.g. captured by a notebook)
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(fds[0], 1)
        os.dup2(fds[1], 2)
        for fd in (*fds, devnull):
            os.close(fd)


class ToolWorld:
    """pybullet scene of rake, toy and table driven by iCub arm trajectories.

    Use as a context manager (or call :meth:`close`) to release the pybullet client.
    ``gui=True`` opens pybullet's viewer instead of the headless DIRECT mode.
    """

    def __init__(self, config: WorldConfig | None = None, gui: bool = False) -> None:
        import pybullet
        from pybullet_utils import bullet_client

        self.cfg = config or WorldConfig()
        cfg = self.cfg
        self.kin = ArmKinematics(
            root_height=cfg.root_height,
            grasp=torch.tensor(cfg.grasp, dtype=torch.float32),
            rake_head_offset=tuple(cfg.rake_head_offset),
        )
        self._postures = torch.tensor(cfg.postures, dtype=torch.float32)
        self.kin.check_limits(self._postures)
        sub = cfg.control_dt / cfg.physics_dt
        if abs(sub - round(sub)) > 1e-6:
            raise ValueError(
                f"WorldConfig.control_dt ({cfg.control_dt}) must be a whole multiple of physics_dt ({cfg.physics_dt})"
            )
        self.substeps = int(round(sub))
        self.p = pybullet
        with _quiet():
            self.client = bullet_client.BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        c = self.client
        c.setGravity(0, 0, -9.81)
        c.setTimeStep(cfg.physics_dt)
        urdf = Path(cfg.urdf_dir)
        with _quiet():
            self.table = c.loadURDF(str(urdf / "table.urdf"), [0.55, 0.0, cfg.table_top], useFixedBase=True)
            self.toy = c.loadURDF(str(urdf / "toy.urdf"), self._toy_start())
            self.rake = c.loadURDF(str(urdf / "rake.urdf"), [0, 0, 2])
        for body in (self.table, self.toy, self.rake):
            c.changeDynamics(body, -1, lateralFriction=cfg.friction)
        c.changeDynamics(self.toy, -1, mass=cfg.toy_mass)
        c.changeDynamics(self.rake, -1, mass=cfg.rake_mass)
        # the rake frame is the grip; pybullet's base frame is the inertial frame: keep the offset
        self._rake_com = np.array(c.getDynamicsInfo(self.rake, -1)[3])
        self._rake_com_orn = c.getDynamicsInfo(self.rake, -1)[4]
        self.constraint = c.createConstraint(
            self.rake, -1, -1, -1, pybullet.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 0, 2]
        )
        self.timing = {"physics_s": 0.0, "tensor_s": 0.0, "render_s": 0.0}
        self.reset(1)

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        if getattr(self, "client", None) is not None:
            with contextlib.suppress(Exception):
                self.client.disconnect()
            self.client = None

    def __enter__(self) -> "ToolWorld":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()

    # ------------------------------------------------------------------ scene
    def _toy_start(self) -> list[float]:
        cfg = self.cfg
        return [cfg.toy_xy[0], cfg.toy_xy[1], cfg.table_top + cfg.toy_size / 2 + 1e-4]

    def initial_posture(self, k: int) -> torch.Tensor:
        """Joint angles (7,) in rad of initial posture ``k`` (1..4)."""
        if not isinstance(k, (int, np.integer)) or not 1 <= int(k) <= 4:
            raise UserInputError(f"posture must be 1, 2, 3 or 4, got {k!r}")
        return self._postures[int(k) - 1].clone()

    def _rake_target(self, T: np.ndarray) -> tuple[list[float], tuple[float, ...]]:
        """Base (inertial-frame) pose pybullet needs so that the rake's grip frame is at ``T``."""
        pos, orn = self._rake_targets(T[None])
        return pos[0].tolist(), tuple(orn[0].tolist())

    def _rake_targets(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Batched :meth:`_rake_target`: (S, 4, 4) grip poses -> positions (S, 3), quaternions (S, 4)."""
        from scipy.spatial.transform import Rotation

        R_com = np.array(self.client.getMatrixFromQuaternion(self._rake_com_orn)).reshape(3, 3)
        pos = T[:, :3, 3] + T[:, :3, :3] @ self._rake_com
        orn = Rotation.from_matrix(T[:, :3, :3] @ R_com).as_quat()
        return pos, orn

    def _set_rake(self, T: np.ndarray, teleport: bool, target=None) -> None:
        """Drive the rake's grip frame to world pose ``T`` (teleport: also place it there now)."""
        pos, orn = self._rake_target(T) if target is None else target
        if teleport:
            self.client.resetBasePositionAndOrientation(self.rake, pos, orn)
            self.client.resetBaseVelocity(self.rake, [0, 0, 0], [0, 0, 0])
        self.client.changeConstraint(
            self.constraint, jointChildPivot=pos, jointChildFrameOrientation=orn, maxForce=self.cfg.rake_max_force
        )

    def reset(self, posture: int, q: torch.Tensor | None = None, toy_xy: tuple[float, float] | None = None) -> None:
        """Put the arm (and so the rake) at ``posture`` (or joint vector ``q``) and the toy at its start."""
        q0 = self.initial_posture(posture) if q is None else q
        self.kin.check_limits(q0)
        T = self.kin.rake_pose(q0).detach().double().numpy()
        self._set_rake(T, teleport=True)
        start = self._toy_start()
        if toy_xy is not None:
            start[:2] = [float(toy_xy[0]), float(toy_xy[1])]
        self.client.resetBasePositionAndOrientation(self.toy, start, [0, 0, 0, 1])
        self.client.resetBaseVelocity(self.toy, [0, 0, 0], [0, 0, 0])
        for _ in range(self.cfg.settle_steps):
            self.client.stepSimulation()

    def toy_xy(self) -> tuple[float, float]:
        pos, _ = self.client.getBasePositionAndOrientation(self.toy)
        return float(pos[0]), float(pos[1])

    # ------------------------------------------------------------------ checks
    def check_trajectories(self, trajectories: torch.Tensor) -> None:
        """Raise a clear ``ValueError`` for a malformed, NaN or out-of-limit trajectory batch."""
        if not isinstance(trajectories, torch.Tensor) or trajectories.dim() != 3 or trajectories.shape[-1] != 7:
            shape = tuple(trajectories.shape) if isinstance(trajectories, torch.Tensor) else type(trajectories)
            raise UserInputError(f"trajectories must be a tensor (N, T, 7), got {shape}")
        if trajectories.shape[1] < 1:
            raise UserInputError("trajectories must have at least one time step")
        self.kin.check_limits(trajectories)

    # ------------------------------------------------------------------ FK filter
    def _rake_points(self) -> torch.Tensor:
        """Sample points (P, 4) on the rake's handle and head, in the rake (grip) frame."""
        L = self.cfg.rake_length
        hx, hy, hz = self.cfg.rake_head_offset
        handle = [(x, 0.0, 0.0) for x in np.linspace(0.0, L, 11)]
        c, s = math.cos(-0.4363323), math.sin(-0.4363323)  # head plate pitch (urdf/rake.urdf)
        head = []
        for dx in (-0.01, 0.01):
            for dy in np.linspace(-0.08, 0.08, 5):
                for dz in (-0.025, 0.0, 0.025):
                    head.append((hx + c * dx + s * dz, hy + dy, hz - s * dx + c * dz))
        pts = torch.tensor(handle + head, dtype=torch.float32)
        return torch.cat([pts, torch.ones(len(pts), 1)], dim=1)

    def near_toy(
        self, trajectories: torch.Tensor, toy_xy: tuple[float, float] | None = None, poses: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Bool (N,): does the rake ever come within ``filter_margin`` of the toy's box?

        Uses batched FK only (no physics).  A rollout with False here cannot move the toy.
        ``poses`` (N, T, 4, 4) are the rake poses if already computed.
        """
        cfg = self.cfg
        tx, ty = toy_xy if toy_xy is not None else cfg.toy_xy
        if poses is None:
            poses = self.kin.rake_pose(trajectories)  # (N, T, 4, 4)
        pts = torch.einsum("ntij,pj->ntpi", poses, self._rake_points())[..., :3]
        h = cfg.toy_size / 2
        lo = torch.tensor([tx - h, ty - h, cfg.table_top])
        hi = torch.tensor([tx + h, ty + h, cfg.table_top + cfg.toy_size])
        gap = torch.clamp(torch.maximum(lo - pts, pts - hi), min=0.0).norm(dim=-1)  # distance to the box
        return gap.flatten(1).min(dim=1).values < cfg.filter_margin

    # ------------------------------------------------------------------ rollouts
    def rollout(
        self,
        trajectories: torch.Tensor,
        posture: int,
        watched: str | None = None,
        use_filter: bool = True,
    ) -> list[Outcome]:
        """Run each joint trajectory (N, T, 7) from initial posture ``posture``; one Outcome each.

        Each trajectory is executed from a freshly reset scene (arm at the posture, toy at its
        start).  Trajectories should start at the posture (a DMP with ``y0`` = the posture does).
        With ``watched`` set, a rollout stops when that event fires; with None it runs to the end.
        ``use_filter`` skips the physics for rollouts whose rake never comes near the toy.
        """
        import time

        if watched is not None:
            event_index(watched)
        self.initial_posture(posture)
        self.check_trajectories(trajectories)
        t0 = time.perf_counter()
        traj = trajectories.detach().to(torch.float32)
        with torch.no_grad():
            poses_t = self.kin.rake_pose(traj)  # (N, T, 4, 4)
            near = self.near_toy(traj, poses=poses_t) if use_filter else torch.ones(len(traj), dtype=torch.bool)
        poses = poses_t.double().numpy()
        self.timing["tensor_s"] += time.perf_counter() - t0
        outcomes = []
        for n in range(len(traj)):
            if not bool(near[n]):
                xy = tuple(float(v) for v in self.cfg.toy_xy)
                outcomes.append(
                    Outcome((False,) * 6, None, (0.0, 0.0), traj.shape[1] - 1, xy, False, simulated=False)
                )
                continue
            t1 = time.perf_counter()
            outcomes.append(self._simulate(poses[n], posture, traj[n, 0], watched))
            self.timing["physics_s"] += time.perf_counter() - t1
        return outcomes

    def _simulate(self, poses: np.ndarray, posture: int, q0: torch.Tensor, watched: str | None) -> Outcome:
        cfg, c = self.cfg, self.client
        self.reset(posture)
        start = np.array(self.toy_xy())
        top = cfg.table_top + cfg.toy_size
        fired = [False] * 6
        first: str | None = None
        blew_up = False
        watched_i = None if watched is None else EVENTS.index(watched)
        step = 0
        targets_pos, targets_orn = self._rake_targets(poses)
        targets_pos, targets_orn = targets_pos.tolist(), targets_orn.tolist()
        for step in range(len(poses)):
            self._set_rake(poses[step], teleport=False, target=(targets_pos[step], targets_orn[step]))
            for _ in range(self.substeps):
                c.stepSimulation()
            pos, _ = c.getBasePositionAndOrientation(self.toy)
            vel, _ = c.getBaseVelocity(self.toy)
            if (
                not all(map(math.isfinite, pos))
                or math.sqrt(sum(v * v for v in vel)) > cfg.max_toy_speed
                or abs(pos[2] - (cfg.table_top + cfg.toy_size / 2)) > cfg.max_toy_height
            ):
                blew_up = True
                break
            d = np.array(pos[:2]) - start
            now = [
                pos[0] < cfg.retrieve_x,
                False,
                -d[0] > cfg.move_threshold,
                d[0] > cfg.move_threshold,
                d[1] > cfg.move_threshold,
                -d[1] > cfg.move_threshold,
            ]
            if not fired[1]:
                for cp in c.getContactPoints(self.rake, self.toy):
                    on_toy, normal = cp[6], cp[7]  # position on B (the toy), normal from B to A
                    if on_toy[2] >= top - cfg.touch_tolerance and abs(normal[2]) >= cfg.touch_normal_z:
                        now[1] = True
                        break
            for i, f in enumerate(now):
                if f and not fired[i]:
                    fired[i] = True
                    if first is None:
                        first = EVENTS[i]
            if watched_i is not None and fired[watched_i]:
                break
        final = self.toy_xy()
        if blew_up:
            return Outcome((False,) * 6, None, (0.0, 0.0), step, tuple(float(v) for v in start), True)
        disp = (final[0] - float(start[0]), final[1] - float(start[1]))
        return Outcome(tuple(fired), first, disp, step, final, False)

    # ------------------------------------------------------------------ camera
    def camera(self) -> tuple[list[float], list[float], list[float]]:
        """Eye position, look-at target and up vector from FK of the head plus the eye's gaze."""
        eye = self.kin.eye_pose()[:3, 3].tolist()
        t, pn = self.cfg.eye_tilt, self.cfg.eye_pan
        d = [math.cos(t) * math.cos(pn), math.cos(t) * math.sin(pn), -math.sin(t)]
        return eye, [e + v for e, v in zip(eye, d)], [0.0, 0.0, 1.0]

    def observe(
        self,
        posture: int | None = None,
        q: torch.Tensor | None = None,
        toy_xy: tuple[float, float] | None = None,
    ) -> dict[str, np.ndarray | torch.Tensor]:
        """Render the eye camera; return the image and the colour-filtered toy and rake maps.

        With ``posture``/``q``/``toy_xy`` given the scene is reset to that state first; otherwise
        the current state is rendered.  Returns ``image`` (H, W, 3) uint8, ``toy`` and ``rake``
        (H, W) float32 masks in {0, 1} (torch tensors).
        """
        import time

        if posture is not None or q is not None:
            self.reset(posture or 1, q=q, toy_xy=toy_xy)
        t0 = time.perf_counter()
        cfg, c = self.cfg, self.client
        eye, target, up = self.camera()
        view = c.computeViewMatrix(eye, target, up)
        proj = c.computeProjectionMatrixFOV(cfg.camera_fov, cfg.image_width / cfg.image_height, 0.02, 3.0)
        _, _, rgba, _, _ = c.getCameraImage(
            cfg.image_width, cfg.image_height, view, proj, renderer=self.p.ER_TINY_RENDERER
        )
        image = np.asarray(rgba, dtype=np.uint8).reshape(cfg.image_height, cfg.image_width, 4)[..., :3].copy()
        toy, rake = colour_masks(image)
        self.timing["render_s"] += time.perf_counter() - t0
        return {"image": image, "toy": toy, "rake": rake}


def colour_masks(image: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """Colour filtering of an RGB image into the red-toy and green-rake maps (float 0/1)."""
    rgb = torch.from_numpy(np.ascontiguousarray(image)).to(torch.float32)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    toy = (r > 60) & (r > 2.0 * g) & (r > 2.0 * b)
    rake = (g > 60) & (g > 2.0 * r) & (g > 2.0 * b)
    return toy.to(torch.float32), rake.to(torch.float32)
