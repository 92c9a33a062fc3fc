"""The pieces of a long measurement (babbling's postures x seeds, the world check's skill libraries)
run in this process or in worker processes (joblib), their results in the pieces' order, with a
progress bar on stderr. An interrupt (Ctrl-C, SIGTERM) or a failed piece stops the workers still
running; what the finished pieces kept on disk (``files.kept_json``) stays there for a rerun.

No worker outlives the process that started it, whatever stopped that process (``kill -9``, an
out-of-memory kill, a cluster's time limit): every pool of workers is made by :func:`parallel`,
whose workers watch their parent's PID from a thread (:func:`watch_parent`) and exit within a
second of its death; a job that Hydra's joblib launcher runs does the same (:func:`guard`, called
by the command line's wrapper). loky's resource trackers then see their pipe close and exit too.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence


PARENT_POLL_S = 0.5  # how often a worker looks whether its parent is still there
_WATCHED: list[int] = []  # the parent PID this process watches (once per process)


def _exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: it exists
        pass
    return True


def _watch(parent: int, ppid: int, period: float) -> None:
    import time

    while True:
        if os.getppid() != ppid or not _exists(parent):  # re-parented, or the parent is gone
            os._exit(1)
        time.sleep(period)


def watch_parent(parent: int | None = None, period: float = PARENT_POLL_S) -> None:
    """End this process within ``period`` seconds of the death of process ``parent`` (default: the
    current parent), or of its own parent (a fork server between them), from a daemon thread that
    polls both PIDs; at most one per process. A parent already gone ends this process now."""
    ppid = os.getppid()
    parent = ppid if parent is None else parent
    if _WATCHED or parent == os.getpid():  # watched already; or run in the parent itself (no worker)
        return
    if not _exists(parent):
        os._exit(1)
    _WATCHED.append(parent)
    threading.Thread(target=_watch, args=(parent, ppid, period), name="watch-parent", daemon=True).start()


def guard() -> None:
    """In a worker process of a pool (joblib, multiprocessing, Hydra's joblib launcher): watch the
    parent (:func:`watch_parent`). Does nothing in a process started otherwise (a shell's)."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        watch_parent()


def parallel(n_jobs: int, **kwargs):
    """joblib's ``Parallel`` whose workers end with this process (:func:`watch_parent`)."""
    from joblib import Parallel

    return Parallel(n_jobs=n_jobs, initializer=watch_parent, initargs=(os.getpid(),), **kwargs)


def _terminate_as_interrupt(signum, frame):
    raise KeyboardInterrupt


def run_pieces(fn: Callable, pieces: Sequence[tuple], jobs: int, desc: str, unit: str = " piece") -> list:
    """``[fn(*p) for p in pieces]``, in ``jobs`` worker processes when ``jobs`` > 1 (``fn`` and the
    pieces must then pickle); the same results in the same order either way. In the main thread,
    SIGTERM is an interrupt while the pieces run (a ``KeyboardInterrupt``, so that the workers are
    stopped rather than left running); the previous handler is restored after."""
    from tqdm.auto import tqdm

    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate_as_interrupt) if main else None
    bar = tqdm(total=len(pieces), desc=desc, unit=unit, file=sys.stderr, disable=None)
    out = []
    try:
        if jobs == 1:
            for p in pieces:
                out.append(fn(*p))
                bar.update()
        elif pieces:
            from joblib import delayed

            results = parallel(min(jobs, len(pieces)), return_as="generator")(delayed(fn)(*p) for p in pieces)
            try:
                for r in results:
                    out.append(r)
                    bar.update()
            except BaseException:
                with warnings.catch_warnings():  # joblib's note on the pieces it cancels
                    warnings.simplefilter("ignore", UserWarning)
                    results.close()  # stops the workers still running
                raise
    finally:
        bar.close()
        if main:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
    return out
