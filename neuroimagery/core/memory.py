"""Peak memory of a phase of a run: the peak resident set size (RSS) of this process.

Torch's CPU allocator keeps no peak counter, so what is measured is the operating system's
high-water mark of the process's resident memory (``resource.getrusage(...).ru_maxrss``): every
tensor, Python object and loaded library that was in RAM at the worst moment, not the memory of
other processes (Experiment 5's parallel task workers report nothing here). On Linux the mark is
reset at the start of each phase (``/proc/self/clear_refs``), so a phase's figure is its own peak,
the memory already resident when it began included; elsewhere it is the peak since the process
started. Where ``resource`` is missing (Windows) the figures are ``None``.
"""
from __future__ import annotations

import sys

try:
    import resource
except ImportError:  # pragma: no cover - Windows
    resource = None


def reset_peak() -> bool:
    """Start a new high-water mark at the current RSS (Linux); False where it cannot be reset."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def peak_rss_mb() -> float | None:
    """The process's peak resident memory in MiB (since the last :func:`reset_peak` on Linux).

    On Linux the high-water mark of the address space (``VmHWM``, the mark :func:`reset_peak`
    resets) is read: ``getrusage`` also keeps marks a reset cannot lower, such as the resident set
    of the process image an ``exec`` replaced (a run started from a large parent).
    """
    hwm = _status_mb("VmHWM:")
    if hwm is not None:
        return hwm
    if resource is None:
        return None
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(kb / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)  # bytes on macOS, KiB elsewhere


def _status_mb(field: str) -> float | None:
    """A ``kB`` field of ``/proc/self/status`` in MiB (Linux; None elsewhere)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field):
                    return round(int(line.split()[1]) / 1024, 1)
    except (OSError, ValueError, IndexError):
        pass
    return None


def rss_mb() -> float | None:
    """The process's resident memory now, in MiB (Linux; None elsewhere)."""
    return _status_mb("VmRSS:")
