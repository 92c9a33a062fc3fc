"""Numba compilation of a module's loop functions (the kernels of :mod:`~neuroimagery.nn.local_kernel`
and :mod:`~neuroimagery.models.voxel_code_kernel`): each loop ``_name`` of the module is compiled the
first time ``name`` is asked for, once, also when several threads ask at the same time."""
from __future__ import annotations

import threading
from typing import Any, Callable, Mapping

try:
    import numba
except ImportError:  # the callers then run their torch code
    numba = None


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
            return self._compiled[name]
