"""The tool-use world of thesis ch. 7: a table, a red toy and a green rake held by the iCub.

Only the rake, the toy and the table take part in the physics.  The iCub's body is represented by
its kinematics: the right arm's joint trajectory goes through batched forward kinematics
(:class:`~neuroimagery.robot.kinematics.ArmKinematics`) and the fixed grasp gives the pose the rake
must have at every control step.

Rake drive (docs/robot.md): the rake is put at pose t-1 with the velocity that carries it to pose
t and pybullet's substeps resolve rake-toy and toy-table contact; the table meets the rake by
``table_contact`` (``rake_plan.table_poses``); control steps far from a resting toy are skipped
(``skip_far_steps``). pybullet resolves the contacts; the toy moves only when pushed.

Compass and events: :mod:`neuroimagery.robot.events` (south = toward the robot, -x; west = its
left, +y). Each event, once fired, stays fired; a rollout stops at the first control step where the
watched event has fired (the thesis stops the arm as soon as the event of interest happens).
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import torch

from neuroimagery.core.errors import UserInputError
from neuroimagery.core.native import quiet_native_output
from neuroimagery.robot.config import WorldConfig
from neuroimagery.robot.events import Outcome, latch_events, watched_indices, toy_events, toy_fate, toy_yaw_of
from neuroimagery.robot.eye import colour_masks
from neuroimagery.robot.kinematics import ArmKinematics
from neuroimagery.robot import arm_yield, rake_plan

# the rake's first points (``_rake_points``) lie on the handle's axis, a cylinder of this radius
# (urdf/rake.urdf); the others lie on the plate's surface
HANDLE_POINTS = 11
HANDLE_RADIUS_M = 0.008


class ToolWorld:
    """pybullet scene of rake, toy and table driven by iCub arm trajectories.

    Use as a context manager (or call :meth:`close`) to release the pybullet client.
    ``gui=True`` opens pybullet's viewer instead of the headless DIRECT mode.
    """

    def __init__(self, config: WorldConfig | None = None, gui: bool = False) -> None:
        import pybullet

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
        self._load_scene(gui)
        self.timing = {"physics_s": 0.0, "tensor_s": 0.0, "render_s": 0.0}
        self._reset_cache: dict[bytes, tuple] = {}
        self._settled: dict[tuple[float, float], tuple] = {}
        self.steps_simulated = 0  # control steps that went through the physics (kinematic drive)
        self.steps_total = 0  # control steps of all simulated rollouts
        self.physics_steps = 0  # pybullet steps those control steps took (kinematic drive)
        self.reset(1)

    def _load_scene(self, gui: bool) -> None:
        """The pybullet client with table, toy and rake, their dynamics, the rake's geometry and its drive."""
        from pybullet_utils import bullet_client

        pybullet, cfg = self.p, self.cfg
        with quiet_native_output():
            self.client = bullet_client.BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        c = self.client
        c.setGravity(0, 0, -9.81)
        c.setTimeStep(cfg.physics_dt)
        self._n_now = self.substeps  # physics steps per control step now set in pybullet
        urdf = Path(cfg.urdf_dir)
        with quiet_native_output():
            self.table = c.loadURDF(str(urdf / "table.urdf"), [0.55, 0.0, cfg.table_top], useFixedBase=True)
            self.toy = c.loadURDF(str(urdf / "toy.urdf"), self._toy_start())
            self.rake = c.loadURDF(str(urdf / "rake.urdf"), [0, 0, 2])
        for body in (self.table, self.toy, self.rake):
            c.changeDynamics(body, -1, lateralFriction=cfg.friction)
        c.changeDynamics(self.toy, -1, mass=cfg.toy_mass)
        # the rake frame is the grip; pybullet's base frame is the inertial frame: keep the offset
        self._rake_com = np.array(c.getDynamicsInfo(self.rake, -1)[3])
        self._rake_com_orn = c.getDynamicsInfo(self.rake, -1)[4]
        self._cid = c._client
        self._R_com = np.array(c.getMatrixFromQuaternion(self._rake_com_orn)).reshape(3, 3)
        pts = self._rake_points()
        self._rake_points_np = pts.double().numpy()
        self._point_radius = np.where(np.arange(len(pts)) < HANDLE_POINTS, HANDLE_RADIUS_M, 0.0)
        self._point_radius_max = HANDLE_RADIUS_M
        self._geometry = rake_plan.RakeGeometry(self._rake_points_np[:, :3], self._point_radius,
                                                self._point_radius_max, self._R_com, self._rake_com)
        # the table meets the rake through the table rule of ``_plan``: rake-table collisions are
        # not computed
        c.setCollisionFilterPair(self.rake, self.table, -1, -1, 0)
        # a heavy rake barely yields to the toy during the substeps between two imposed poses
        m0 = c.getDynamicsInfo(self.rake, -1)[0]
        inertia = np.array(c.getDynamicsInfo(self.rake, -1)[2]) * (cfg.rake_mass / m0)
        c.changeDynamics(self.rake, -1, mass=cfg.rake_mass, localInertiaDiagonal=inertia.tolist())

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

    def reset(self, posture: int, q: torch.Tensor | None = None, toy_xy: tuple[float, float] | None = None,
              toy_yaw: float | None = None) -> None:
        """Put the arm (and so the rake) at ``posture`` (or joint vector ``q``) and the toy at its
        start (or at ``toy_xy``, turned by ``toy_yaw`` rad about the vertical)."""
        q0 = self.initial_posture(posture) if q is None else q
        start = self._toy_start()
        if toy_xy is not None:
            start[:2] = [float(toy_xy[0]), float(toy_xy[1])]
        yaw = float(toy_yaw or 0.0)
        toy_orn = [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
        c = self.client
        q_np = np.asarray(torch.as_tensor(q0, dtype=torch.float32).detach().numpy(), dtype=np.float32)
        key = q_np.tobytes()
        pose = self._reset_cache.get(key)
        if pose is None:
            self.kin.check_limits(torch.as_tensor(q_np))
            plan = self._plan(q_np[None, None])  # the table rule, as every driven pose
            pose = (plan["pos"][0, 0].tolist(), plan["orn"][0, 0].tolist())
            if len(self._reset_cache) > 256:
                self._reset_cache.clear()
            self._reset_cache[key] = pose
        # the toy settles on the table alone (a kinematic rake has nothing holding it up), then
        # the rake is put in place, at rest.  Settling is deterministic, so the settled pose of
        # the toy at each start point is computed once and then reused.
        c.resetBasePositionAndOrientation(self.rake, [0.0, 0.0, 2.0], [0, 0, 0, 1])
        settled = self._settled.get((start[0], start[1], yaw))
        if settled is None:
            c.resetBasePositionAndOrientation(self.toy, start, toy_orn)
            c.resetBaseVelocity(self.toy, [0, 0, 0], [0, 0, 0])
            self._set_physics_step(self.substeps)
            for _ in range(self.cfg.settle_steps):
                c.stepSimulation()
            settled = c.getBasePositionAndOrientation(self.toy)
            if len(self._settled) > 256:
                self._settled.clear()
            self._settled[(start[0], start[1], yaw)] = settled
        c.resetBasePositionAndOrientation(self.toy, settled[0], settled[1])
        c.resetBaseVelocity(self.toy, [0, 0, 0], [0, 0, 0])
        c.resetBasePositionAndOrientation(self.rake, pose[0], pose[1])
        c.resetBaseVelocity(self.rake, [0, 0, 0], [0, 0, 0])

    def toy_xy(self) -> tuple[float, float]:
        pos, _ = self.client.getBasePositionAndOrientation(self.toy)
        return float(pos[0]), float(pos[1])

    def toy_yaw(self) -> float:
        """The toy's present turn about the vertical (rad, folded by :func:`toy_yaw_of`)."""
        return toy_yaw_of(self.client.getBasePositionAndOrientation(self.toy)[1])

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
        for dx in (-self.cfg.rake_plate[0] / 2, self.cfg.rake_plate[0] / 2):
            for dy in np.linspace(-self.cfg.rake_plate[1] / 2, self.cfg.rake_plate[1] / 2, 5):
                for dz in np.linspace(-self.cfg.rake_plate[2] / 2, self.cfg.rake_plate[2] / 2, 5):
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
        watched: str | tuple[str, ...] | None = None,
        use_filter: bool = True,
    ) -> list[Outcome]:
        """Run each joint trajectory (N, T, 7) from initial posture ``posture``; one Outcome each.

        Each trajectory is executed from a freshly reset scene (arm at the posture, toy at its
        start).  Trajectories should start at the posture (a DMP with ``y0`` = the posture does).
        With ``watched`` set (one event or several), a rollout stops as soon as one of them fires;
        with None it runs to the end.
        ``use_filter`` skips the physics for rollouts whose rake never comes near the toy.
        """
        watched_indices(watched)  # a clear error for an unknown name
        self.initial_posture(posture)
        self.check_trajectories(trajectories)
        t0 = time.perf_counter()
        traj = trajectories.detach().to(torch.float32)
        N, T = traj.shape[:2]
        plan = self._plan(traj.numpy())
        return self._rollout_kinematic(plan, posture, watched, use_filter, t0)

    def _rollout_kinematic(self, plan: dict, posture: int, watched, use_filter: bool, t0: float) -> list[Outcome]:
        """The default drive's rollouts: physics only for those whose rake comes near the toy."""
        arm = plan["arm_step"]
        N, T = arm.shape
        plan["gaps0"] = self._gaps(plan["pts"], self.cfg.toy_xy, plan["sweep"])  # toy at its start
        if use_filter:
            near = plan["gaps0"].min(axis=-1) < self.cfg.filter_margin
        else:
            near = np.ones(N, dtype=bool)
        self.timing["tensor_s"] += time.perf_counter() - t0
        outcomes = []
        for n in range(N):
            if not near[n]:
                outcomes.append(dataclasses.replace(self._skipped(T), min_gap=float(max(plan["gaps0"][n].min(), 0.0)),
                                                    arm_step=int(arm[n, T - 1])))
                continue
            t1 = time.perf_counter()
            out = self._simulate_kinematic({k: v[n] for k, v in plan.items()}, posture, watched)
            outcomes.append(dataclasses.replace(out, min_gap=float(max(plan["gaps0"][n].min(), 0.0)),
                                                arm_step=int(arm[n, out.stop_step])))
            self.timing["physics_s"] += time.perf_counter() - t1
        return outcomes

    def _skipped(self, T: int) -> Outcome:
        """Outcome of a rollout the FK filter showed cannot touch the toy."""
        xy = tuple(float(v) for v in self.cfg.toy_xy)
        return Outcome((False,) * 6, None, (0.0, 0.0), T - 1, xy, False, simulated=False)

    # ---------------------------------------------------------------- kinematic drive (default)
    def _plan(self, q: np.ndarray) -> dict:
        """Joint trajectories ``q`` (N, T, 7) -> everything about them that does not depend on the
        toy (:func:`rake_plan.plan`; the yielding arm's poses under :mod:`robot.arm_yield`)."""
        q = np.asarray(q, dtype=np.float64)
        if self.cfg.table_contact != "yield":
            return rake_plan.plan(self.kin.rake_pose_np(q), self._geometry, self.cfg, self.substeps)
        poses, arm = arm_yield.yielded_poses(self.kin, q, self._geometry, self.cfg)
        return rake_plan.plan(poses, self._geometry, self.cfg, self.substeps, arm_step=arm)

    def _gaps(self, pts: np.ndarray, toy_xy, sweep: np.ndarray) -> np.ndarray:
        """Per control step, the rake's smallest distance to the toy's box (:func:`rake_plan.gaps`)."""
        return rake_plan.gaps(pts, toy_xy, sweep, self.cfg, self._geometry.point_radius_max)

    def _set_physics_step(self, n: int) -> None:
        """``n`` physics steps per control step from now on (the step is ``control_dt / n``)."""
        if n != self._n_now:
            h = self.cfg.physics_dt if n == self.substeps else self.cfg.control_dt / n
            self.p.setTimeStep(h, physicsClientId=self._cid)
            self._n_now = n

    def _simulate_kinematic(self, plan: dict, posture: int, watched) -> Outcome:
        """Rake driven kinematically; physics only while the rake can reach the toy (module doc).

        ``plan``: one trajectory's entries of :meth:`_plan` (without the batch axis).
        """
        cfg, p, cid = self.cfg, self.p, self._cid
        T = len(plan["pos"])
        start, start_yaw, gaps = self._start(plan, posture)
        fired = [False] * 6
        first: str | None = None
        blew_up = off_table = False
        # the fastest any rake point has moved up to each control step (blow-up rule, toy_fate)
        rake_speed = rake_plan.fastest_so_far(plan["sweep"], cfg)
        watched_i = watched_indices(watched)
        margin = cfg.filter_margin
        drive = [plan[k].tolist() for k in ("pos", "orn", "lin", "ang", "nsub")]
        resting = True  # the toy is still (so steps far from it cannot change anything)
        last = 0
        t = 1
        n_sim = n_phys = 0
        while t < T:
            if resting and cfg.skip_far_steps:
                ahead = np.flatnonzero(gaps[t:] < margin)
                if len(ahead) == 0:
                    last = T - 1
                    break
                t += int(ahead[0])
            n = self._drive_step(drive, t)
            n_sim += 1
            n_phys += n
            last = t
            fate, first, pos, now_resting = self._watch_toy(start, rake_speed[t], fired, first)
            if fate == "blew_up":
                blew_up = True
                break
            if fate == "off_table":
                off_table = True
                break
            if any(fired[i] for i in watched_i):
                break
            was_resting, resting = resting, now_resting
            if resting and not was_resting:
                gaps[t + 1:] = self._gaps(plan["pts"][t:], (pos[0], pos[1]), plan["sweep"][t:])[1:]
            t += 1
        else:
            last = T - 1
        self.steps_simulated += n_sim
        self.physics_steps += n_phys
        self.steps_total += T
        if blew_up:
            return Outcome((False,) * 6, None, (0.0, 0.0), last, (float(start[0]), float(start[1])), True,
                           final_toy_yaw=start_yaw)
        final, final_orn = p.getBasePositionAndOrientation(self.toy, physicsClientId=cid)
        return Outcome(tuple(fired), first, (final[0] - float(start[0]), final[1] - float(start[1])), last,
                       (float(final[0]), float(final[1])), False, final_toy_yaw=toy_yaw_of(final_orn),
                       off_table=off_table)

    def _watch_toy(self, start, rake_speed: float, fired: list, first):
        """The toy after a control step: its fate (:func:`toy_fate`), the events latched into ``fired``
        (unless it blew up), the first event, its place and whether it rests."""
        p, cid, cfg = self.p, self._cid, self.cfg
        pos = p.getBasePositionAndOrientation(self.toy, physicsClientId=cid)[0]
        vel, avel = p.getBaseVelocity(self.toy, physicsClientId=cid)
        fate = toy_fate(pos, vel, rake_speed, cfg)
        if fate == "blew_up":
            return fate, first, pos, False
        now = toy_events(pos[0], pos[1], pos[0] - start[0], pos[1] - start[1], cfg,
                         height=pos[2] - (cfg.table_top + cfg.toy_size / 2))
        first = latch_events(now, fired, first, cfg.table_top + cfg.toy_size, cfg,
                             lambda: p.getContactPoints(self.rake, self.toy, physicsClientId=cid))
        speed = math.sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2])
        v_rest = cfg.rest_speed
        return fate, first, pos, speed < v_rest and math.sqrt(avel[0] ** 2 + avel[1] ** 2 + avel[2] ** 2) < 20 * v_rest

    def _drive_step(self, drive: list, t: int) -> int:
        """Control step ``t`` of the kinematic drive: the rake put at pose t-1 with the velocity that
        carries it to pose t (``drive``: the plan's pos, orn, lin, ang, nsub as lists), then its
        physics substeps; returns their number."""
        p, cid = self.p, self._cid
        pos_l, orn_l, lin_l, ang_l, nsub_l = drive
        p.resetBasePositionAndOrientation(self.rake, pos_l[t - 1], orn_l[t - 1], physicsClientId=cid)
        p.resetBaseVelocity(self.rake, lin_l[t], ang_l[t], physicsClientId=cid)
        n = nsub_l[t]
        self._set_physics_step(n)
        for _ in range(n):
            p.stepSimulation(physicsClientId=cid)
        return n

    def _start(self, plan: dict, posture: int) -> tuple[tuple, float, np.ndarray]:
        """The scene reset at ``posture``: the toy's settled place and heading, and the rake's
        distance to it per control step (the plan's own when the toy settled at its start)."""
        self.reset(posture)
        start_pos, start_orn = self.p.getBasePositionAndOrientation(self.toy, physicsClientId=self._cid)
        start, start_yaw = (start_pos[0], start_pos[1]), toy_yaw_of(start_orn)
        if math.hypot(start[0] - self.cfg.toy_xy[0], start[1] - self.cfg.toy_xy[1]) < 1e-4:
            start = tuple(self.cfg.toy_xy)  # settled at its start (gaps to it are already known)
        if start == tuple(self.cfg.toy_xy) and "gaps0" in plan:
            return start, start_yaw, plan["gaps0"].copy()
        return start, start_yaw, self._gaps(plan["pts"], start, plan["sweep"])

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
        toy_yaw: float | None = None,
    ) -> dict[str, np.ndarray | torch.Tensor]:
        """Render the eye camera; return the image and the colour-filtered toy and rake maps.

        With ``posture``/``q``/``toy_xy``/``toy_yaw`` given the scene is reset to that state first; otherwise
        the current state is rendered.  Returns ``image`` (H, W, 3) uint8, ``toy`` and ``rake``
        (H, W) float32 masks in {0, 1} (torch tensors).
        """
        if posture is not None or q is not None:
            self.reset(posture or 1, q=q, toy_xy=toy_xy, toy_yaw=toy_yaw)
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


