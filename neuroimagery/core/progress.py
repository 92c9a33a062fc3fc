"""Progress bars of a run's training and test phases (tqdm, on stderr).

``neuroimagery.app.run`` opens a :func:`phase` around an experiment's ``train`` and ``evaluate``; the
protocol code shared by Experiments 1-4 reports its work into it: :func:`bar` wraps a loop of
known length (a bar ``exp4 train: forward model``), :func:`advance` counts finished trials on one
bar per phase (``exp4 test: 1440/2160 trials``, with the block just finished); :func:`expect`
gives that bar its total before the first block, so it shows how far the phase is and an ETA. Nothing is shown outside
a phase or with ``progress=false``, and an experiment that reports nothing (Exp. 5 has its own bar)
shows nothing. Each phase that showed work leaves one line in the job log: ``done in X s``, or, for a phase that did
not finish, that it stopped.
"""
from __future__ import annotations

import contextlib
import sys
import time
from typing import Iterable, Iterator

from tqdm.auto import tqdm

from .console import LOG


class _Phase:
    def __init__(self, label: str, enabled: bool) -> None:
        self.label, self.enabled = label, enabled
        self.counter: tqdm | None = None
        self.counted, self.unit = 0, ""
        self.bars = 0
        self.t0 = time.perf_counter()

    def bar(self, iterable, total, what: str, unit: str) -> tqdm:
        self.bars += 1
        return tqdm(iterable, total=total, desc=f"{self.label}: {what}", unit=unit, file=sys.stderr,
                    disable=not self.enabled, dynamic_ncols=True)

    def _counter(self, unit: str, total: int | None = None) -> tqdm:
        if self.counter is None:
            self.unit = unit
            self.counter = tqdm(total=total, desc=self.label, unit=f" {unit}", file=sys.stderr,
                                disable=not self.enabled, dynamic_ncols=True)
        elif total is not None:
            self.counter.total = total
            self.counter.refresh()
        return self.counter

    def expect(self, total: int, unit: str) -> None:
        self._counter(unit, int(total))

    def advance(self, n: int, unit: str, note: str) -> None:
        self._counter(unit)
        self.counted += n
        if note:
            self.counter.set_postfix_str(note, refresh=False)
        self.counter.update(n)

    def close(self, stopped: BaseException | None = None) -> None:
        """One line in the job log: ``done in X s`` for a phase that finished; for one that did
        not, that it stopped, and why (an interrupt, or an error)."""
        if self.counter is not None:
            self.counter.close()
        took = time.perf_counter() - self.t0
        if stopped is not None:
            why = "interrupted" if isinstance(stopped, KeyboardInterrupt) else f"stopped by {type(stopped).__name__}"
            so_far = f" after {self.counted} {self.unit}" if self.counter is not None else ""
            LOG.warning(f"{self.label}: {why}{so_far}, {took:.1f} s in; not finished")
        elif self.counter is not None or self.bars:
            done = f"{self.counted} {self.unit} " if self.counter is not None else ""
            LOG.info(f"{self.label}: {done}done in {took:.1f} s")
            total = None if self.counter is None else self.counter.total
            if total is not None and total != self.counted:  # the announced total was wrong
                LOG.warning(f"{self.label}: counted {self.counted} of the {total} {self.unit} announced")


_current: _Phase | None = None


@contextlib.contextmanager
def phase(label: str, enabled: bool) -> Iterator[None]:
    """Bars opened inside are labelled ``label`` (e.g. ``exp4 train``); ``enabled`` false hides them."""
    global _current
    outer, _current = _current, _Phase(label, enabled)
    try:
        yield
    except BaseException as err:
        _current.close(stopped=err)
        _current = outer
        raise
    _current.close()
    _current = outer


def bar(iterable: Iterable | None = None, total: int | None = None, what: str = "", unit: str = "it") -> tqdm:
    """A tqdm bar over ``iterable`` (or one to ``update()`` by hand) in the running phase; a
    disabled bar (it passes the items through) outside a phase."""
    if _current is None:
        return tqdm(iterable, total=total, disable=True)
    return _current.bar(iterable, total, what, unit)


def expect(total: int, unit: str = "trials") -> None:
    """Say that the running phase will count ``total`` ``unit`` in all: its bar shows the share
    done and an ETA (call it before the first :func:`advance`)."""
    if _current is not None:
        _current.expect(total, unit)


def advance(n: int, unit: str = "trials", note: str = "") -> None:
    """Count ``n`` finished ``unit`` on the running phase's bar (``note``: what just finished)."""
    if _current is not None:
        _current.advance(n, unit, note)
