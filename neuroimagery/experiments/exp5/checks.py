"""Checks of Experiment 5 that run before any work (``neuroimagery.validation.check_run``):

- ``experiment.world.environment`` names a class that can be imported (``module:Class``), so a
  misspelt module is refused before the first task, not in every worker;
- ``experiment.engine.reuse_libraries`` names a run of Experiment 5 (its ``manifest.json`` says
  so, or its ``checkpoints/`` holds Experiment 5's task files): another experiment's run would be
  read as holding no library and every library computed again without a word.
"""
from __future__ import annotations

import importlib
from pathlib import Path

from ...core.errors import UserInputError
from ...core.manifest import usable_run


def check_environment(spec: str) -> None:
    """``spec`` is ``robot`` or ``module:Class`` of an importable class."""
    if spec == "robot":
        return
    mod, _, cls = spec.partition(":")
    try:
        module = importlib.import_module(mod)
    except ImportError as err:  # ModuleNotFoundError included
        raise UserInputError(f"experiment.world.environment={spec!r}: cannot import {mod!r} ({err})") from None
    except Exception as err:  # the module itself failed while importing: still the user's module
        raise UserInputError(f"experiment.world.environment={spec!r}: importing {mod!r} failed "
                             f"({type(err).__name__}: {err})") from None
    if not callable(getattr(module, cls, None)):
        raise UserInputError(f"experiment.world.environment={spec!r}: {mod!r} has no class {cls!r}")


def check_reuse(path: str) -> None:
    """``path`` (if set) is a run directory of Experiment 5."""
    if not path:
        return
    root = Path(path)
    key = f"experiment.engine.reuse_libraries={path!r}"
    if (root / "manifest.json").is_file():  # each task file is checked again when its library is read
        usable_run(root, key, experiment="exp5", need="any", files=None)
        return
    if not any((root / "checkpoints").glob("exp5_*.pt")):
        raise UserInputError(f"{key} holds no task files of exp5 (checkpoints/exp5_*.pt): not a run of exp5")


def check_inputs(cfg) -> None:
    e = cfg.experiment
    check_environment(e.world.environment)
    check_reuse(e.engine.reuse_libraries)
