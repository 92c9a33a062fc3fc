"""Numba for the package's compiled loops (:mod:`~neuroimagery.nn.local_kernel`,
:mod:`~neuroimagery.nn.som_windowed_kernel`, :mod:`~neuroimagery.nn.hebbian_closed_form`,
:mod:`~neuroimagery.motor.dmp_kernel`, :mod:`~neuroimagery.models.voxel_code_kernel`): whether it is installed, a loop made a numba
function, and :class:`Kernels`, which compiles each loop ``_name`` of a module the first time
``name`` is asked for, once, also when several threads ask at the same time. Without numba the
callers run their torch code."""
from __future__ import annotations

import threading
from typing import Any, Callable, Mapping

import torch

try:
    import numba
except ImportError:  # the callers then run their torch code (the same numbers, more slowly)
    numba = None


def installed() -> bool:
    """Whether numba is installed."""
    return numba is not None


def available() -> bool:
    """Whether compiled loops can run now: numba installed, and not while ``torch.compile`` traces."""
    return numba is not None and not torch.compiler.is_compiling()


def jit(f: Callable) -> Callable:
    """``f`` made a numba function (compiled at its first call), so that compiled loops can call it;
    ``f`` itself without numba."""
    return numba.njit(cache=True, nogil=True)(f) if numba is not None else f


class Kernels:
    """``Kernels(globals())("name")``: the compiled ``_name`` of that module's namespace."""

    def __init__(self, namespace: Mapping[str, Any]) -> None:
        self._namespace = namespace
        self._compiled: dict[str, Callable] = {}
        self._lock = threading.Lock()

    def __call__(self, name: str) -> Callable:
        with self._lock:
            if name not in self._compiled:
                self._compiled[name] = numba.njit(cache=True, nogil=True)(self._namespace["_" + name])
                _say_if_compiling(self._compiled[name])
            return self._compiled[name]


FIRST_COMPILE = ("compiling the package's numba loops on their first use (a few seconds: Exp 2's and Exp 6's "
                 "measured within the noise of their training time); numba caches them beside the package "
                 "(__pycache__/*.nbi, *.nbc), so later runs skip this")
_said = threading.Event()


def _say_if_compiling(dispatcher) -> None:
    """One ``note:`` per process, the first time a loop is compiled rather than read from numba's
    cache (its index file is missing)."""
    if _said.is_set():
        return
    try:
        import os

        cached = os.path.exists(dispatcher._cache._cache_file._index_path)
    except Exception:  # noqa: BLE001 - another numba's internals: say nothing
        return
    if not cached:
        _said.set()
        from ..core.console import note

        note(FIRST_COMPILE)
