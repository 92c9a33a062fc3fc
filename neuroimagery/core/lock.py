"""The lock of a run directory: a run writing into a directory holds ``DIR/run.lock`` (the host,
the PID and the start time of its process) until it ends, so a second run into the same directory
is refused, naming the holder. A lock whose process is gone (killed) on this host is taken over
with a ``note:``; a lock held on another host cannot be checked from here and is refused, saying
how to remove it if that run is gone.

The lock file is made whole under a temporary name and then linked to ``run.lock`` (a link
fails when the name exists), so a reader never sees a half-written lock.
"""
from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from . import console
from .errors import UserInputError
from .files import tmp_path, unlink_quietly

NAME = "run.lock"


def _start_ticks(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, Linux); None where unknown."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return int(f.read().rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _alive(pid: int, started: int | None) -> bool:
    """Is process ``pid`` of this host running (and the same process: its start time matches)?"""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        pass
    except (OSError, OverflowError, ValueError):
        return False
    if started is not None:
        now = _start_ticks(pid)
        if now is not None and now != started:  # the PID was reused by another process
            return False
    return True


def me() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid(), "started": _start_ticks(os.getpid())}


def read(root: str | Path) -> dict | None:
    """The holder recorded in ``root/run.lock``; None without one; ``{}`` for an unreadable lock."""
    path = Path(root) / NAME
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def holder_alive(holder: dict) -> bool | None:
    """True: its process runs; False: gone (this host); None: another host (cannot be checked)."""
    if holder.get("host") != socket.gethostname():
        return None
    pid = holder.get("pid")
    if not isinstance(pid, int):
        return False
    return _alive(pid, holder.get("started"))


class RunLock:
    """``acquire()`` the lock of ``root`` or refuse; ``release()`` it (only if it is still ours)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.path = self.root / NAME
        self.held = False

    def check(self) -> None:
        """Refuse, writing nothing, a directory whose lock a live run holds (or a run on another
        host); a lock left by a killed run passes (:meth:`acquire` takes it over)."""
        holder = read(self.root)
        if holder:
            self._refuse_if_held(holder)

    def _refuse_if_held(self, holder: dict) -> None:
        alive = holder_alive(holder)
        host, pid = holder.get("host", "?"), holder.get("pid", "?")
        if alive:
            raise UserInputError(f"{self.root} is being written by another run (host {host}, PID {pid}; lock "
                                 f"{self.path}): wait for it to end, or choose another directory")
        if alive is None:
            raise UserInputError(f"{self.root} is locked by a run on host {host}, PID {pid} ({self.path}); if that "
                                 "run is gone, remove the lock file, or choose another directory")

    def acquire(self) -> "RunLock":
        self.check()
        mine = me()
        tmp = tmp_path(self.path)
        tmp.write_text(json.dumps(mine) + "\n")
        try:
            for _ in range(3):
                try:
                    os.link(tmp, self.path)
                    self.held = True
                    return self
                except FileExistsError:
                    pass
                except OSError:  # a file system without hard links: an exclusive create
                    try:
                        fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
                    except FileExistsError:
                        pass
                    else:
                        with os.fdopen(fd, "w") as f:
                            f.write(json.dumps(mine) + "\n")
                        self.held = True
                        return self
                self._take_over_if_stale()
            raise UserInputError(f"{self.root}: cannot take its lock {self.path} (another run keeps taking it)")
        finally:
            unlink_quietly(tmp)

    def _take_over_if_stale(self) -> None:
        holder = read(self.root)
        if holder is None:  # released meanwhile
            return
        if not holder:  # unreadable: left by a process killed while it wrote the lock
            console.note(f"{self.root}: its lock {self.path} is unreadable (left by a killed run?); taking it over")
            unlink_quietly(self.path)
            return
        self._refuse_if_held(holder)
        pid = holder.get("pid", "?")
        console.note(f"{self.root}: its lock was held by PID {pid} on this host, which is gone (killed?); taking it over")
        unlink_quietly(self.path)

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        holder = read(self.root)
        if holder and holder.get("pid") == os.getpid() and holder.get("host") == socket.gethostname():
            unlink_quietly(self.path)
