"""Names of a package imported from their modules on first use (PEP 562), so that importing one
light module of the package does not import all the others (torch, numba, the simulator)."""
from __future__ import annotations

import importlib
import sys
from typing import Any, Callable, Mapping


def lazy_names(package: str, where: Mapping[str, str]) -> Callable[[str], Any]:
    """The module ``__getattr__`` of ``package`` exporting ``where``'s names: ``{name: module}``, the
    module relative to the package (``".som"``) or absolute; each is imported on its first use."""

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(where[name], package), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__
