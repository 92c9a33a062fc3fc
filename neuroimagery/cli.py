"""Command-line wrappers: a user's mistake becomes one line on stderr and exit status 2."""
from __future__ import annotations

import functools
import sys

from .errors import UserInputError


def friendly_errors(fn):
    """Run ``fn``; print a :class:`UserInputError` as ``error: ...`` and exit 2 (tracebacks stay for bugs)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except UserInputError as e:
            print(f"error: {e}", file=sys.stderr)
            sys.exit(2)
        except KeyboardInterrupt:
            print("interrupted: files already written in the run directory are kept", file=sys.stderr)
            sys.exit(130)

    return wrapper
