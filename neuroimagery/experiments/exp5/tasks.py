"""Experiment 5 task files (``checkpoints/exp5_<task>.pt``): written atomically, read as plain data.

A task file holds tensors, dicts, lists, tuples, str, int, float, bool and None only (the skill
library as ``Library.to_state()``), so it is read back with ``torch.load(weights_only=True)``:
a file holding anything else (a pickle that would run code on load) is refused, naming it, and
nothing in it runs.

Every write goes to a temporary file named after the writing process
(``exp5_<task>.pt.<pid>.tmp``) and is then renamed over the target, so a reader never sees half a
file and two writers (a run and its rerun, two workers) never share a temporary name. A failed
write (read-only directory, full disk) becomes a :class:`UserInputError` naming the path; files
written before it are kept.
"""
from __future__ import annotations

import os
import pickle
import re
import warnings
from pathlib import Path

import torch

from ...core.errors import UserInputError
from ...core.files import torch_save, unlink_quietly, write_atomic

# what a task file must hold, and of which type (every version of the format has had these)
TASK_KEYS = {"task": dict, "rows": list, "library": dict, "timing": dict, "config": dict}


def save(obj, path: str | Path) -> Path:
    """``torch.save(obj)`` into ``path`` atomically (:func:`neuroimagery.core.files.write_atomic`); an
    ``OSError`` becomes a :class:`UserInputError` naming ``path``."""
    try:
        return write_atomic(path, lambda tmp: torch_save(obj, tmp))
    except OSError as err:
        raise UserInputError(f"cannot write {path}: {err.strerror or err}") from None


def load(path: str | Path):
    """``torch.load`` of plain data only; a file that holds anything else, or cannot be read, is
    refused with a one-line :class:`UserInputError` naming it."""
    path = Path(path)
    try:
        with warnings.catch_warnings():  # a foreign pickle's protocol warning: the error below says it all
            warnings.simplefilter("ignore", UserWarning)
            return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # a forbidden object, cut short, unreadable, or something else under this name
        text = str(err).strip()
        what = re.search(r"Unsupported global: GLOBAL (\S+)", text)
        if isinstance(err, pickle.UnpicklingError) and what:
            raise UserInputError(f"{path}: refused, it holds objects other than tensors and plain data "
                                 f"({what.group(1)}); neuroimagery does not write such files") from None
        reason = (getattr(err, "strerror", None) or text.partition("WeightsUnpickler error:")[2].strip() or text
                  or type(err).__name__)
        raise UserInputError(f"{path}: refused, not a readable task file ({reason.splitlines()[0]}); "
                             "delete it to compute the task again") from None


def read_task(path: str | Path) -> dict | None:
    """The task stored at ``path`` (None if there is none), refused unless it is plain data with
    the keys of a task file."""
    path = Path(path)
    if not path.exists():
        return None
    d = load(path)
    bad = [k for k, kind in TASK_KEYS.items() if not isinstance(d, dict) or not isinstance(d.get(k), kind)]
    if bad:
        raise UserInputError(f"{path}: not an Exp 5 task file (no {', '.join(bad)}); delete it to compute the task again")
    return d


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def remove_stale(directory: str | Path, pattern: str = "exp5_*.pt.*.tmp") -> list[Path]:
    """Remove the temporary files in ``directory`` whose writer (the pid in the name) is gone: a
    worker stopped in the middle of a write leaves one. Returns the files removed."""
    out = []
    for p in Path(directory).glob(pattern):
        pid = p.name.rsplit(".", 2)[-2]
        if pid.isdigit() and not _alive(int(pid)):
            unlink_quietly(p)
            out.append(p)
    return out
