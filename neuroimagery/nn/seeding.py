"""Per-participant random number generators.

Every simulated participant owns a :class:`torch.Generator` seeded from ``(seed, participant)``,
so participant ``p`` of a batched run of ``P`` participants draws exactly the numbers a solo run
of participant ``p`` draws. Blocks that need randomness take a list of generators (one per
participant) and stack the per-participant draws.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence

import torch

from .functional import thread_budget

PARALLEL_DRAW = 1 << 20  # numbers per participant from which the participants' draws run side by side

_MIX = 0x9E3779B97F4A7C15  # golden-ratio constant, spreads nearby seeds apart


def participant_seed(seed: int, participant: int, stream: int = 0) -> int:
    """Deterministic 63-bit seed of one participant's random stream."""
    if seed < 0 or participant < 0 or stream < 0:
        raise ValueError(f"seed, participant and stream must be >= 0, got {seed}, {participant}, {stream}")
    x = (seed * 1_000_003 + participant * 7919 + stream * 104_729 + 1) * _MIX
    return x % (2**63 - 1)


def participant_generators(seed: int, participants: int | Sequence[int], stream: int = 0) -> list[torch.Generator]:
    """One generator per participant.

    ``participants`` is a count ``P`` (participants ``0..P-1``) or an explicit list of
    participant indices (so a solo run of participant 3 is ``participant_generators(seed, [3])``).
    ``stream`` separates independent uses (initial weights, training order, trial noise ...).
    """
    ids = list(range(participants)) if isinstance(participants, int) else list(participants)
    if not ids:
        raise ValueError("participants must be >= 1")
    gens = []
    for p in ids:
        g = torch.Generator()
        g.manual_seed(participant_seed(seed, p, stream))
        gens.append(g)
    return gens


def stacked(generators: Sequence[torch.Generator], draw: Callable[[torch.Generator], torch.Tensor]) -> torch.Tensor:
    """Stack ``draw(g)`` over the participants' generators along a new leading axis."""
    return torch.stack([draw(g) for g in generators])


def uniform(generators: Sequence[torch.Generator], shape: Sequence[int], low: float = 0.0, high: float = 1.0) -> torch.Tensor:
    """U[low, high) of shape ``(P, *shape)``, one participant per generator."""
    out = torch.empty((len(generators), *shape))
    shape = tuple(shape)

    def draw(pair) -> None:  # in place: no per-participant copies to stack
        torch.rand(shape, generator=pair[1], out=pair[0])

    workers = min(thread_budget(), len(generators))
    if workers > 1 and out[0].numel() >= PARALLEL_DRAW:
        # each generator is a sequential stream of its own, so large draws of several participants
        # run side by side on the run's threads (torch releases the GIL); the numbers are the same
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(draw, zip(out, generators)))
    else:
        for pair in zip(out, generators):
            draw(pair)
    if high - low != 1:
        out.mul_(high - low)
    return out.add_(low) if low != 0 else out  # adding 0 to U[0, 1) samples changes no bit


def randint(generators: Sequence[torch.Generator], high: int, shape: Sequence[int]) -> torch.Tensor:
    """Integers in ``[0, high)`` of shape ``(P, *shape)``."""
    return stacked(generators, lambda g: torch.randint(high, tuple(shape), generator=g))
