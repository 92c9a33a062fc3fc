"""What a run tells its user, one line at a time.

Each line is printed as it is (results on stdout; notes, errors and interruptions on stderr) and
also passed to the ``neuroimagery`` logger (``logging.getLogger("neuroimagery")``), so the job log
that Hydra keeps in the run directory (``<run dir>/<job>.log``, see ``conf/hydra/job_logging``)
holds the same lines with a time stamp. The printed line never carries a logging prefix: an
``error:`` line on stderr stays exactly one line.
"""
from __future__ import annotations

import logging
import sys

LOG = logging.getLogger("neuroimagery")
# a library's logger: without a handler of its own, Python would print WARNING records on stderr a
# second time (logging.lastResort) wherever nothing configured logging
LOG.addHandler(logging.NullHandler())


def info(message: str) -> None:
    """A result line (where the report is, what was trained) on stdout."""
    print(message)
    LOG.info(message)


def note(message: str) -> None:
    """``note: message`` on stderr: something the user should know, not a failure."""
    line = f"note: {message}"
    print(line, file=sys.stderr)
    LOG.warning(line)


def error(message: str) -> None:
    """``error: message`` on stderr: why the command stopped (the caller exits)."""
    line = f"error: {message}"
    print(line, file=sys.stderr)
    LOG.error(line)


def interrupted(message: str) -> None:
    """A line on stderr after an interruption (Ctrl-C, SIGTERM)."""
    print(message, file=sys.stderr)
    LOG.warning(message)
