"""Command-line wrappers: a user's mistake becomes one line on stderr and exit status 2."""
from __future__ import annotations

import functools
import signal
import sys
import threading

from .errors import UserInputError


def _terminate_as_interrupt(signum, frame):
    raise KeyboardInterrupt


def friendly_errors(fn):
    """Run ``fn``; print a :class:`UserInputError` as ``error: ...`` and exit 2 (tracebacks stay for bugs).

    SIGTERM is handled as SIGINT while ``fn`` runs (a ``KeyboardInterrupt`` in the main thread,
    so workers are stopped and finished files kept); the previous handler is restored after.
    """

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, _terminate_as_interrupt) if main else None
        try:
            return fn(*args, **kwargs)
        except UserInputError as e:
            print(f"error: {e}", file=sys.stderr)
            sys.exit(2)
        except KeyboardInterrupt:
            print("interrupted: files already written in the run directory are kept", file=sys.stderr)
            sys.exit(130)
        finally:
            if main:
                signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)

    return wrapper
