"""The pieces of a long measurement (babbling's postures x seeds, the world check's skill libraries)
run in this process or in worker processes (joblib), their results in the pieces' order, with a
progress bar on stderr. An interrupt (Ctrl-C, SIGTERM) or a failed piece stops the workers still
running; what the finished pieces kept on disk (``files.kept_json``) stays there for a rerun."""
from __future__ import annotations

import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence


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
            from joblib import Parallel, delayed

            results = Parallel(n_jobs=min(jobs, len(pieces)), return_as="generator")(delayed(fn)(*p) for p in pieces)
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
