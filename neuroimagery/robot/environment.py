"""The pybullet rake-and-toy world as the tool-use model's environment (thesis ch. 7).

:class:`ToolWorldEnvironment` offers the model what it needs from a world (the ``Environment``
protocol of :mod:`neuroimagery.models.tool_use`): start an initial situation, draw random
movements around a posture, execute DMP primitives from any scene (:class:`State`) and return
what they did (:class:`Result`), render the PC map of a scene and read the toy-related reward
from an image.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .config import OFF_TABLE_XY
from .eye import ToyReader

@dataclass(frozen=True)
class State:
    """A scene: the initial posture it started from, and (after moves) the arm and toy state.

    ``q`` / ``toy_xy`` are None for the untouched initial situation of ``posture``; ``toy_yaw`` is
    the toy's turn about the vertical (rad), None when it is square (or not tracked).
    """

    posture: int
    q: tuple[float, ...] | None = None
    toy_xy: tuple[float, float] | None = None
    toy_yaw: float | None = None


@dataclass(frozen=True)
class Result:
    """What executing one primitive did: events (``EVENTS`` order), the state it left."""

    events: tuple[bool, ...]
    next_state: State
    fired_first: str | None = None
    blew_up: bool = False  # the physics blew up (all events are then False)
    off_table: bool = False  # the toy fell off the table: the next state keeps it out of play

    def fired(self, name: str) -> bool:
        from .events import event_index

        return bool(self.events[event_index(name)])

    @property
    def retrieved(self) -> bool:
        return bool(self.events[0])


class ToolWorldEnvironment:
    """:class:`Environment` over the pybullet rake-and-toy world (``robot.world.ToolWorld``).

    Primitives are DMPs (``motor.dmp.DMP``, 7 goals + 28 shape weights) rolled out from the
    arm's current joints. A scene after earlier moves (arm elsewhere, toy displaced) is restored
    through ``ToolWorld.reset(q=..., toy_xy=..., toy_yaw=...)`` before the next rollout.

    A scene keeps the toy where and as the last move left it (its place and its turn about the
    vertical): the simulator keeps whatever a move left.

    A primitive's 7 goal numbers are joint angles (thesis: 7 goal parameters, one per joint):
    every rollout of a primitive ends in the same arm posture whatever the start, its shape
    rescaled by ``g - y0`` (eq. 7.3). A movement is bounded by the joint limits only. Random
    primitives and their goal noise follow ``robot.movements`` (docs/robot.md).
    """

    def __init__(self, world_config=None, duration_s: float = 1.5, explore_weight_sigma: float = 300.0,
                 search_goal_sigma: float = 0.05, search_weight_sigma: float = 30.0) -> None:
        from .movements import MovementConfig, world_dmp
        from .world import ToolWorld

        class _World(ToolWorld):
            """ToolWorld whose rollouts can start from a given arm and toy state."""

            start_state: tuple | None = None

            def reset(self, posture, q=None, toy_xy=None, toy_yaw=None):
                if q is None and toy_xy is None and self.start_state is not None:
                    q, toy_xy, toy_yaw = self.start_state
                super().reset(posture, q=q, toy_xy=toy_xy, toy_yaw=toy_yaw)

        self.world = _World(world_config)
        self.dmp = world_dmp()
        self.n_params = self.dmp.n_params
        cfg = self.world.cfg
        self.image_shape = (cfg.image_height, cfg.image_width)
        self.duration_s, self.dt = float(duration_s), float(cfg.control_dt)
        self.moves = MovementConfig(weight_sigma=float(explore_weight_sigma), duration_s=float(duration_s),
                                    dt=float(cfg.control_dt))
        J, B = self.dmp.n_joints, self.dmp.n_basis
        self._sigma = torch.cat([torch.full((J,), float(search_goal_sigma)), torch.full((J * B,), float(search_weight_sigma))])
        self._images: dict[State, torch.Tensor] = {}
        self.reader = ToyReader(self.world)
        self.timing = {"rollout_s": 0.0, "render_s": 0.0, "rollouts": 0, "renders": 0}

    def close(self) -> None:
        self.world.close()

    def start(self, posture: int) -> State:
        return State(int(posture))

    def _q(self, state: State) -> torch.Tensor:
        return self.world.initial_posture(state.posture) if state.q is None else torch.tensor(state.q)

    def random_primitive(self, generator: torch.Generator) -> torch.Tensor:
        """A free DMP's random parameters (``robot.movements.random_primitives``)."""
        from .movements import random_primitives

        return random_primitives(self.world, self.dmp, 1, self.moves, generator)[0]

    def explore_params(self, params: torch.Tensor, posture: int, n: int, generator: torch.Generator) -> torch.Tensor:
        """``n`` exploratory rollouts of a DMP from ``posture`` (``robot.movements.explore``: the DMP
        reinitialised with the posture, noise added to its goals; docs/contracts.md, W9)."""
        from .movements import explore

        return explore(self.world, self.dmp, params.float().expand(n, -1), self.world.initial_posture(posture), generator)

    def search_sigma(self) -> torch.Tensor:
        return self._sigma.clone()

    def execute(self, params: torch.Tensor, state: State, watched: str | None) -> list[Result]:
        import time

        t0 = time.perf_counter()
        q0 = self._q(state)
        traj = self.world.kin.clamp(self.dmp.rollout(params.float(), q0, self.duration_s, self.dt))
        fresh = state.q is None and state.toy_xy is None and state.toy_yaw is None
        self.world.start_state = None if fresh else (q0, state.toy_xy, state.toy_yaw)
        try:
            outs = self.world.rollout(traj, state.posture, watched=watched, use_filter=fresh)
        finally:
            self.world.start_state = None
        res = []
        for n, o in enumerate(outs):
            arm = o.stop_step if o.arm_step is None else o.arm_step  # the joints the arm holds
            q_end = tuple(round(float(v), 6) for v in traj[n, arm])
            toy = tuple(round(float(v), 6) for v in o.final_toy_xy)
            yaw = round(float(o.final_toy_yaw), 6)
            if o.off_table:  # out of play from now on (docs/robot.md, a toy thrown off the table)
                toy, yaw = OFF_TABLE_XY, 0.0
            res.append(Result(tuple(bool(e) for e in o.events), State(state.posture, q_end, toy, yaw or None),
                              o.fired_first, bool(o.blew_up), bool(o.off_table)))
        self.timing["rollout_s"] += time.perf_counter() - t0
        self.timing["rollouts"] += len(outs)
        return res

    def _observe(self, state: State) -> dict:
        """The eye's view of ``state`` (``ToolWorld.observe`` after setting the scene up)."""
        q = None if state.q is None else torch.tensor(state.q)
        return self.world.observe(posture=state.posture, q=q, toy_xy=state.toy_xy, toy_yaw=state.toy_yaw)

    def perceive(self, state: State) -> torch.Tensor:
        import time

        if state not in self._images:
            t0 = time.perf_counter()
            obs = self._observe(state)
            self._images[state] = torch.stack([obs["toy"], obs["rake"]]).to(torch.uint8)
            self.timing["render_s"] += time.perf_counter() - t0
            self.timing["renders"] += 1
        return self._images[state].float()

    def eye_image(self, state: State) -> np.ndarray:
        """The RGB image the eye sees in ``state`` (for figures)."""
        return self._observe(state)["image"]

    def reader_bias(self) -> float:
        """Mean error (m) of the toy reader near the reachable area's border (``eye.ToyReader.bias``)."""
        return self.reader.bias()

    def reward(self, image: torch.Tensor) -> float:
        """1 if the toy, read from the image (blob centre projected back onto the table, less the
        reader's bias), lies in the reachable area."""
        return 1.0 if self.reader.in_reach(image[0]) else 0.0
