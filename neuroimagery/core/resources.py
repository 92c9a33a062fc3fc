"""What this process may use (memory, cores), and the check of a run's needs against it before any work.

The memory a process may use is the smallest of the limits that apply to it: the cgroup's
``memory.max`` (v2) or ``memory.limit_in_bytes`` (v1) less what the cgroup already uses, the
address-space limit ``RLIMIT_AS``, the memory the kernel can still give (``MemAvailable``), and a
SLURM allocation (``SLURM_MEM_PER_NODE``, or ``SLURM_MEM_PER_CPU`` times the CPUs of the task).
The cores are the smallest of the CPU set (``os.sched_getaffinity``), the cgroup's CPU quota
(``cpu.max`` / ``cpu.cfs_quota_us``) and ``SLURM_CPUS_PER_TASK``, never ``os.cpu_count()``, which
counts the whole machine.

An experiment (:class:`neuroimagery.core.experiment.Experiment`) may provide ``memory_estimate(conf) -> [Need]``: the bytes of the largest
arrays the run must hold at once, each named by the setting that sizes it. The estimates count
only those arrays (weights, training sets, banks of maps), so they are lower bounds of the peak:
a run refused by :func:`check_resources` could not have fitted. ``allow_large=true`` skips the
memory and thread checks, for a machine whose limits are not visible from here.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from .errors import UserInputError

CGROUP = Path("/sys/fs/cgroup")


@dataclass(frozen=True)
class Need:
    """``bytes`` of memory a run allocates because of the setting ``key`` (``what``: the arrays)."""

    key: str
    bytes: float
    what: str


def culprit(factors: dict[str, tuple[float, float]]) -> str:
    """``key=value`` of the setting furthest above its default among ``{key: (value, default)}``:
    the one to name when their product is too large."""
    key = max(factors, key=lambda k: float(factors[k][0]) / max(float(factors[k][1]), 1e-12))
    value = factors[key][0]
    return f"{key}={value:g}" if isinstance(value, float) else f"{key}={value}"


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def _own_cgroup() -> Path | None:
    """This process's cgroup v2 folder (``/proc/self/cgroup``: ``0::/path``), if mounted."""
    text = _read(Path("/proc/self/cgroup")) or ""
    for line in text.splitlines():
        if line.startswith("0::"):
            d = CGROUP / line[3:].lstrip("/")
            if d.is_dir():
                return d
    return CGROUP if (CGROUP / "cgroup.controllers").exists() else None


def _v1_dirs(controller: str) -> list[Path]:
    """The cgroup v1 folders of ``controller`` that hold this process, innermost first."""
    base = CGROUP / controller
    text = _read(Path("/proc/self/cgroup")) or ""
    for line in text.splitlines():
        parts = line.split(":", 2)
        if len(parts) == 3 and controller in parts[1].split(","):
            d, out = base / parts[2].lstrip("/"), []
            while d.is_dir() and d != base.parent:
                out.append(d)
                if d == base:
                    break
                d = d.parent
            return out or [base]
    return [base]


def _meminfo(field: str) -> int | None:
    for line in (_read(Path("/proc/meminfo")) or "").splitlines():
        if line.startswith(field + ":"):
            try:
                return int(line.split()[1]) * 1024
            except (IndexError, ValueError):
                return None
    return None


def _int(text: str | None) -> int | None:
    try:
        return int(text) if text is not None else None
    except ValueError:
        return None


def memory_limits() -> dict[str, int]:
    """``{source: bytes}`` of every limit on this process's memory that can be read here."""
    out: dict[str, int] = {}
    cg = _own_cgroup()
    if cg is not None:  # v2: the limit of this cgroup or of any above it
        d = cg
        while True:
            limit = _int(_read(d / "memory.max"))
            if limit is not None:
                used = _int(_read(d / "memory.current")) or 0
                out.setdefault("cgroup memory.max", max(0, limit - used))
                out["cgroup memory.max"] = min(out["cgroup memory.max"], max(0, limit - used))
            if d == CGROUP or d.parent == d:
                break
            d = d.parent
    for d in _v1_dirs("memory"):
        v1 = _int(_read(d / "memory.limit_in_bytes"))
        if v1 is not None and v1 < 1 << 60:
            used = _int(_read(d / "memory.usage_in_bytes")) or 0
            left = max(0, v1 - used)
            out["cgroup memory.limit_in_bytes"] = min(left, out.get("cgroup memory.limit_in_bytes", left))
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            out["RLIMIT_AS"] = soft
    except (ImportError, OSError, ValueError):  # pragma: no cover - not POSIX
        pass
    avail = _meminfo("MemAvailable")
    if avail is not None:
        out["MemAvailable"] = avail
    per_node = _int(os.environ.get("SLURM_MEM_PER_NODE"))
    if per_node:
        out["SLURM_MEM_PER_NODE"] = per_node * 1024 * 1024
    per_cpu = _int(os.environ.get("SLURM_MEM_PER_CPU"))
    if per_cpu:
        cpus = _int(os.environ.get("SLURM_CPUS_PER_TASK")) or 1
        out["SLURM_MEM_PER_CPU"] = per_cpu * cpus * 1024 * 1024
    return out


def memory_limit() -> tuple[int | None, str]:
    """The memory this process may still use (bytes) and which limit sets it; ``(None, "")`` where
    none can be read."""
    limits = memory_limits()
    if not limits:
        return None, ""
    source = min(limits, key=limits.get)
    return limits[source], source


def core_limits() -> dict[str, int]:
    """``{source: cores}`` of every limit on this process's cores that can be read here."""
    out: dict[str, int] = {}
    try:
        out["CPU affinity"] = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        out["os.cpu_count"] = os.cpu_count() or 1
    cg = _own_cgroup()
    text = _read(cg / "cpu.max") if cg is not None else None
    if text and not text.startswith("max"):
        try:
            quota, period = (int(x) for x in text.split()[:2])
            out["cgroup cpu.max"] = max(1, math.ceil(quota / period))
        except ValueError:
            pass
    for d in _v1_dirs("cpu"):
        quota, period = _int(_read(d / "cpu.cfs_quota_us")), _int(_read(d / "cpu.cfs_period_us"))
        if quota and quota > 0 and period:
            n = max(1, math.ceil(quota / period))
            out["cgroup cpu.cfs_quota_us"] = min(n, out.get("cgroup cpu.cfs_quota_us", n))
    slurm = _int(os.environ.get("SLURM_CPUS_PER_TASK"))
    if slurm:
        out["SLURM_CPUS_PER_TASK"] = slurm
    return out


def core_limit() -> tuple[int, str]:
    """The cores this process may use and which limit sets it."""
    limits = core_limits()
    source = min(limits, key=limits.get)
    return limits[source], source


def human(n: float) -> str:
    """Bytes in words: ``4.0e+14 bytes (364 TiB)``-like, short: ``364 TiB``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if abs(n) < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"  # pragma: no cover


def check_threads(threads: int) -> None:
    """``threads`` (0 = chosen at start-up) must not exceed the cores this process may use."""
    if threads <= 0:
        return
    cores, source = core_limit()
    if threads > cores:
        raise UserInputError(f"threads={threads} but this process may use {cores} core(s) ({source}): more threads "
                             f"than cores only wait for each other; set threads<={cores}, threads=0 (chosen at "
                             "start-up), or allow_large=true to run anyway")


def check_memory(needs: list[Need]) -> None:
    """Refuse a run whose estimated memory exceeds what this process may use, naming the setting
    that needs the most."""
    if not needs:
        return
    total = sum(n.bytes for n in needs)
    limit, source = memory_limit()
    if limit is None or total <= limit:
        return
    top = max(needs, key=lambda n: n.bytes)
    raise UserInputError(f"{top.key} needs about {human(total)} of memory ({top.what}: {human(top.bytes)}), more "
                         f"than this process may use ({human(limit)}, {source}); lower it, or set allow_large=true "
                         "on a machine that has the memory")


def check_resources(conf, module) -> None:
    """Threads against cores and the module's memory estimate against the memory, unless
    ``conf.allow_large``."""
    if getattr(conf, "allow_large", False):
        return
    check_threads(int(getattr(conf, "threads", 0) or 0))
    estimate = module.memory_estimate
    if estimate is not None:
        check_memory(list(estimate(conf)))
