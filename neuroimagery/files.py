"""Writing a result file atomically: into a temporary name of the writing process, then renamed
over the target, so a reader never sees half a file and two writers (a run and its rerun, two
workers) never share a temporary name. Used by the run directory (``neuroimagery.run.RunDir``) and
by Experiment 5's task files."""
from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import torch


def tmp_path(path: str | Path) -> Path:
    """This process's temporary name for ``path``."""
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid()}.tmp")


def unlink_quietly(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


def write_atomic(path: str | Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)`` into this process's temporary name, then rename it to ``path``. The temporary
    file is removed if anything goes wrong (an interrupt included); the error is raised as it came
    (callers name the file to the user)."""
    path = Path(path)
    tmp = tmp_path(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        unlink_quietly(tmp)
        raise
    return path


def torch_save(obj, path: Path) -> None:
    """``torch.save`` into a file opened here (torch reports a failed open or write on a path it
    opens itself as a RuntimeError, not an OSError), flushed to disk before the rename."""
    with open(path, "wb") as f:
        torch.save(obj, f)
        f.flush()
        os.fsync(f.fileno())
