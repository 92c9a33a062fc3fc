"""The command line of every tool of the package (``pool``, ``stimuli``, ``robot.babble``,
``robot.reach``, ``robot.posture_fit``, ``robot.scene_check``, ``experiments.exp5_world``, the
benchmarks): one parser, one set of value types and bounds, one form of refusal.

A bad argument is one ``error:`` line on stderr and exit status 2, as ``evaluate.py`` refuses a bad
setting: :class:`ToolParser` raises :class:`~neuroimagery.core.errors.UserInputError` instead of
printing argparse's usage, :func:`check` applies the declared bounds of settings
(:class:`~neuroimagery.core.bounds.Bounds`) to an option, :func:`check_size` refuses a size past what
a tool allows without ``--allow-large``, and :func:`run_tool` prints the refusal::

    def main(argv=None) -> int:
        return run_tool(_main, argv)

Counts are whole numbers written as ``1000``, ``1e3`` or ``1_000``; a seed is a whole number
>= 0 (the bounds of ``seed=`` of a run); a path is never empty (an unset shell variable gives
``--out ''``, which is refused rather than read as the current folder).
"""
from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence

from .bounds import Bounds
from .errors import UserInputError

SEED = Bounds(ge=0, lt=2 ** 63)  # as ``seed`` of a run (neuroimagery.config.Config)


class ToolParser(argparse.ArgumentParser):
    """argparse whose refusals are the one ``error:`` line of every tool (no usage text); an
    abbreviated option is refused rather than guessed (``--out`` is not ``--outputs``)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        raise UserInputError(message)


def count(text: str) -> int:
    """A whole number given as ``1000``, ``1e6`` or ``1_000``; anything else is refused."""
    try:
        value = float(text.replace("_", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not math.isfinite(value) or value != int(value):
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}")
    return int(value)


def seed(text: str) -> int:
    """A seed: a whole number >= 0."""
    value = count(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"a seed must be >= 0, got {value}")
    if SEED.fails(value):
        raise argparse.ArgumentTypeError(f"a seed must be below 2**63, got {value}")
    return value


def path(text: str) -> str:
    """A path that is not empty (nor blank)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path (an unset variable?)")
    return text


def check(name: str, value, **bounds) -> None:
    """Refuse ``value`` of option ``name`` outside ``bounds`` (those of :class:`Bounds`: ``ge``,
    ``le``, ``choices``, ...), in the words of a setting's refusal."""
    Bounds(**bounds).check(name, value)


def check_size(name: str, value: int, most: int, allow_large: bool, work: str = "") -> None:
    """Refuse ``value`` of option ``name`` above ``most`` unless ``--allow-large`` (``work``: what
    it would cost, in words)."""
    if value > most and not allow_large:
        raise UserInputError(f"{name} {value}: at most {most} without --allow-large{f' ({work})' if work else ''}")


def check_jobs(name: str, jobs: int, allow_large: bool) -> None:
    """Worker processes: at least 1, and no more than the cores this process may use unless
    ``--allow-large`` (:func:`neuroimagery.core.resources.core_limit`)."""
    from .resources import core_limit

    check(name, jobs, ge=1)
    cores, source = core_limit()
    if jobs > cores and not allow_large:
        raise UserInputError(f"{name} {jobs} but this process may use {cores} core(s) ({source}): more workers "
                             "than cores only slow the work down; --allow-large to run them anyway")


def run_tool(fn: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None = None) -> int:
    """``fn(argv)``; a :class:`UserInputError` or an ``OSError`` becomes ``error: ...`` on stderr and
    exit status 2. Returns the exit status (``fn``'s, or 0)."""
    try:
        return fn(argv) or 0
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"error: {os_error_message(err)}", file=sys.stderr)
        return 2


def _terminate_as_interrupt(signum, frame):
    raise KeyboardInterrupt


def run_resumable(fn: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None,
                  kept: Callable[[], str], sigterm: bool = False) -> int:
    """:func:`run_tool` for a tool that keeps its finished pieces for a rerun: an interrupt (Ctrl-C,
    and SIGTERM when ``sigterm``) prints one line, ``interrupted: <kept()>; the same command
    resumes``, and returns 130. ``kept()`` is asked at the interrupt (what was kept, and where)."""
    import signal

    previous = signal.signal(signal.SIGTERM, _terminate_as_interrupt) if sigterm else None
    try:
        return run_tool(fn, argv)
    except KeyboardInterrupt:
        print(f"interrupted: {kept()}; the same command resumes", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def os_error_message(err: OSError) -> str:
    """An ``OSError`` in one line: the file, then why."""
    where = f"{err.filename}: " if getattr(err, "filename", None) else ""
    return f"{where}{err.strerror or err}"
