"""What the tool-use model shares between its parts: the events, the situations and the
:class:`Environment` protocol the model talks to a world through."""
from __future__ import annotations

from typing import Protocol

import torch

from ...robot.environment import Result, State
from ...robot.events import EVENTS

SKILL_LETTERS = ("P", "T", "S", "N", "W", "E")  # Table 7.1 column names of the skills
N_POSTURES = 4


class Environment(Protocol):
    """What the brain needs from a world (the pybullet robot or a stand-in).

    image_shape: (H, W) of one PC channel; the PC vector has ``2 * H * W`` units (toy, tool).
    n_params: length of a primitive's flat parameter vector.
    """

    image_shape: tuple[int, int]
    n_params: int

    def start(self, posture: int) -> State: ...

    def random_primitive(self, generator: torch.Generator) -> torch.Tensor:
        """A free DMP's random parameters (Fig. 7.5 initialisation)."""

    def explore_params(self, params: torch.Tensor, posture: int, n: int, generator: torch.Generator) -> torch.Tensor:
        """``n`` exploratory rollouts of ``params`` from ``posture``: noise added to the goals."""

    def search_sigma(self) -> torch.Tensor:
        """Standard deviation of the PI^BB exploration noise per parameter (eq. 7.6)."""

    def execute(self, params: torch.Tensor, state: State, watched: str | None) -> list[Result]:
        """Run each parameter row from ``state``; stop a row when ``watched`` fires."""

    def perceive(self, state: State) -> torch.Tensor:
        """The PC map of a state: float (2, H, W) in [0, 1] (toy channel, tool channel)."""

    def reward(self, image: torch.Tensor) -> float:
        """The toy-related reward read from a PC image: 1 if the toy lies in reach, else 0."""


__all__ = ["EVENTS", "SKILL_LETTERS", "N_POSTURES", "State", "Result", "Environment"]
