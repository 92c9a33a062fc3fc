"""What a run tells its user, one line at a time.

Each line is printed as it is (results on stdout; notes, errors and interruptions on stderr) and
also passed to the ``neuroimagery`` logger (``logging.getLogger("neuroimagery")``), so the job log
that Hydra keeps in the run directory (``<run dir>/<job>.log``, see ``conf/hydra/job_logging``)
holds the same lines with a time stamp. The printed line never carries a logging prefix: an
``error:`` line on stderr stays exactly one line.

The job log's handler is a :class:`RunLogHandler`: it opens no file until the run has claimed its
directory (:func:`claimed`, called by the run once the directory's lock is taken and the directory
checked), keeping the lines until then; a run refused before that (the directory holds another
run, another run holds its lock, the directory cannot be written) writes nothing into it.
"""
from __future__ import annotations

import logging
import os
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


class RunLogHandler(logging.FileHandler):
    """A job log that is written only once the run has claimed the directory the log lies in
    (:func:`claimed`); the records before are kept and written then, or dropped if it never is."""

    def __init__(self, filename, mode: str = "a", encoding: str | None = None, delay: bool = True, **kw) -> None:
        super().__init__(filename, mode, encoding, delay=True, **kw)
        self.pending: list[logging.LogRecord] | None = []
        _HANDLERS.append(self)

    def emit(self, record: logging.LogRecord) -> None:
        if self.pending is not None:
            self.pending.append(record)
        else:
            super().emit(record)

    def claim(self, root) -> None:
        """The run owns ``root``: if this log lies there, write the kept records and go on writing."""
        if self.pending is None or os.path.dirname(self.baseFilename) != os.path.abspath(root):
            return
        kept, self.pending = self.pending, None
        for record in kept:
            super().emit(record)

    def close(self) -> None:
        if self in _HANDLERS:
            _HANDLERS.remove(self)
        super().close()


_HANDLERS: list[RunLogHandler] = []


def claimed(root) -> None:
    """The run has claimed directory ``root``: a job log kept for it starts writing there."""
    for h in list(_HANDLERS):
        h.claim(root)
