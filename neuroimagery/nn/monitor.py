"""Training curves out of the blocks, without the blocks knowing who reads them.

A block that trains step by step reports what it measures with :func:`record` (a tag, a value, the
block's own step); nothing is kept unless a reader is installed with :func:`to` (a run installs its
TensorBoard logger, so the curves land under ``train/...``). Blocks check :func:`active` before
measuring anything that costs time, so training without a reader does no extra work. Like
``logging``, the reader is process-wide; the context manager restores the previous one.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable, Iterator

Reader = Callable[[str, float, int], None]
_readers: list[Reader] = []


def active() -> bool:
    """Whether a reader is installed (measure only then)."""
    return bool(_readers)


def record(tag: str, value, step: int) -> None:
    """Report ``value`` (a number or a 0-d tensor) at ``step`` of the curve ``tag`` to the reader."""
    if _readers:
        _readers[-1](tag, float(value), int(step))


@contextmanager
def to(reader: Reader) -> Iterator[None]:
    """Send every :func:`record` inside the block to ``reader(tag, value, step)``."""
    _readers.append(reader)
    try:
        yield
    finally:
        _readers.remove(reader)


class Curve:
    """A curve of about ``points`` points over ``total`` steps: :meth:`add` takes a value per step
    and reports the mean of each stretch of ``total // points`` steps at the stretch's last step
    (``offset`` + step); the last stretch is reported however short."""

    def __init__(self, tag: str, total: int, points: int = 100, offset: int = 0) -> None:
        self.tag, self.total, self.offset = tag, int(total), int(offset)
        self.stride = max(1, self.total // max(1, points))
        self._acc: list[float] = []

    def add(self, step: int, value) -> None:
        """``step`` counts from 0 to ``total - 1``."""
        self._acc.append(float(value))
        if (step + 1) % self.stride == 0 or step + 1 == self.total:
            record(self.tag, sum(self._acc) / len(self._acc), self.offset + step + 1)
            self._acc.clear()
