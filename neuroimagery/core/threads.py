"""How many torch intra-op threads a run uses when ``threads=0``: measured at start-up.

Torch's default is one thread per core. When other work keeps cores busy, those threads wait for
each other (OpenMP hand-offs) and a run can become several times slower than on one thread; on an
idle machine the extra threads help. :func:`auto_threads` samples the machine's CPU use for a
tenth of a second (``/proc/stat``) and leaves the busy cores out. The thread count never
changes a result (docs/architecture.md, "Threads").
"""
from __future__ import annotations

import os
import time


def _cpu_times() -> tuple[float, float] | None:
    try:
        with open("/proc/stat") as f:
            fields = [float(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0.0)  # idle + iowait
    return sum(fields), idle


def cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def busy_cores(sample_s: float = 0.1) -> float | None:
    """Cores kept busy by other work over the next ``sample_s`` seconds (None where unknown)."""
    a = _cpu_times()
    if a is None:
        return None
    time.sleep(sample_s)
    b = _cpu_times()
    total, idle = b[0] - a[0], b[1] - a[1]
    if total <= 0:
        return None
    return (1.0 - idle / total) * (os.cpu_count() or 1)


def auto_threads(sample_s: float = 0.1) -> int:
    """The cores of this process's CPU set that other work leaves free (at least 1); all of them
    where CPU use cannot be read."""
    n = cores()
    busy = busy_cores(sample_s)
    if busy is None:
        return n
    return max(1, min(n, int(n - busy + 0.5)))
