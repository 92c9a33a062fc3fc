"""A cheap STAND-IN for the tool-use world, for fast tests only.

It is a 2-D kinematic abstraction (a point-like rake head that drags a point-like toy it runs
into), not the thesis's robot and not its physics: results obtained with it are never reported.
It implements the :class:`neuroimagery.models.tool_use.Environment` protocol with small images.

Coordinates: x north (away from the robot), y west (robot's left); the toy starts at (0.6, 0).
"""
from __future__ import annotations

import torch

from neuroimagery.models.tool_use import EVENTS, Result, State

TOY = (0.6, 0.0)
HEADS = {1: (0.7, 0.0), 2: (0.6, -0.15), 3: (0.45, -0.2), 4: (0.3, -0.3)}  # head at the 4 postures
REACH_X = 0.45
GOAL_BOX = ((0.25, -0.45), (0.85, 0.25))  # (x, y) low and high corners of the goals random DMPs draw
MOVE = 0.03
STEPS = 20


class StandInToolEnv:
    """Stand-in :class:`Environment`: params = (goal x, goal y, bend x, bend y) of the head's path."""

    n_params = 4

    def __init__(self, image_shape=(24, 32), explore_sigma=0.3, search_sigma=0.05):
        self.image_shape = tuple(image_shape)
        self.explore_sigma, self._search = float(explore_sigma), float(search_sigma)
        self.rollouts = 0

    def start(self, posture: int) -> State:
        return State(int(posture))

    def _head_toy(self, state: State):
        head = HEADS[state.posture] if state.q is None else state.q
        toy = TOY if state.toy_xy is None else state.toy_xy
        return torch.tensor(head, dtype=torch.float64), torch.tensor(toy, dtype=torch.float64)

    def random_primitive(self, generator: torch.Generator) -> torch.Tensor:
        """A random primitive: goal uniform over the part of the table the head can reach, bend
        N(0, explore_sigma)."""
        lo, hi = torch.tensor(GOAL_BOX[0]), torch.tensor(GOAL_BOX[1])
        goal = lo + (hi - lo) * torch.rand(2, generator=generator)
        return torch.cat([goal, self.explore_sigma * torch.randn(2, generator=generator)])

    def explore_params(self, params: torch.Tensor, posture: int, n: int, generator: torch.Generator) -> torch.Tensor:
        """The stand-in explores around the head's start whatever the primitive (its cheap world
        needs no more): goal = head + N(0, explore_sigma), bend N(0, explore_sigma)."""
        h = torch.tensor(HEADS[posture])
        goal = h + self.explore_sigma * torch.randn(n, 2, generator=generator)
        bend = self.explore_sigma * torch.randn(n, 2, generator=generator)
        return torch.cat([goal, bend], dim=1)

    def search_sigma(self) -> torch.Tensor:
        return torch.full((4,), self._search)

    def execute(self, params: torch.Tensor, state: State, watched: str | None) -> list[Result]:
        out = []
        w = [] if watched is None else [EVENTS.index(watched)] if isinstance(watched, str) else [EVENTS.index(x) for x in watched]
        for th in params.double():
            self.rollouts += 1
            head, toy = self._head_toy(state)
            start_head, start_toy = head.clone(), toy.clone()
            goal, bend = th[:2], start_head + th[2:]
            fired = [False] * 6
            first = None
            for s in range(1, STEPS + 1):
                t = s / STEPS
                new = (1 - t) ** 2 * start_head + 2 * (1 - t) * t * bend + t * t * goal
                if (new - toy).norm() < 0.06:
                    toy = toy + (new - head)
                    fired[1] = fired[1] or (new - toy).norm() < 0.06
                head = new
                d = toy - start_toy
                now = [bool(toy[0] < REACH_X), fired[1], bool(-d[0] > MOVE), bool(d[0] > MOVE),
                       bool(d[1] > MOVE), bool(-d[1] > MOVE)]
                for i, f in enumerate(now):
                    if f and not fired[i]:
                        fired[i] = True
                        first = first or EVENTS[i]
                fired = [a or b for a, b in zip(fired, now)]
                if any(fired[i] for i in w):
                    break
            nxt = State(state.posture, tuple(round(float(v), 6) for v in head), tuple(round(float(v), 6) for v in toy))
            out.append(Result(tuple(fired), nxt, first))
        return out

    def _pix(self, x, y):
        H, W = self.image_shape
        return int(min(max((1.0 - x) * H, 0), H - 1)), int(min(max((y + 0.5) * W, 0), W - 1))

    def perceive(self, state: State) -> torch.Tensor:
        head, toy = self._head_toy(state)
        img = torch.zeros(2, *self.image_shape)
        r, c = self._pix(*toy.tolist())
        img[0, max(r - 1, 0):r + 2, max(c - 1, 0):c + 2] = 1.0
        for t in torch.linspace(0, 1, 12):  # head bar and handle toward the robot's hand
            x = head[0] * (1 - t) + 0.05 * t
            y = head[1] * (1 - t) - 0.3 * t
            img[1][self._pix(float(x), float(y))] = 1.0
        for dy in (-0.05, 0.0, 0.05):
            img[1][self._pix(float(head[0]), float(head[1] + dy))] = 1.0
        return img

    def reward(self, image: torch.Tensor) -> float:
        toy = image[0]
        m = float(toy.sum())
        if m < 1:
            return 0.0
        rows = torch.arange(toy.shape[0], dtype=torch.float32).unsqueeze(1)
        r = float((rows * toy).sum()) / m
        x = 1.0 - (r + 0.5) / self.image_shape[0]
        return 1.0 if x < REACH_X else 0.0
