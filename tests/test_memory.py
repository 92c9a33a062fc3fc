"""The peak resident memory a run reports (neuroimagery/core/memory.py)."""
import sys

import pytest

PEAK_AND_RESET = """
import torch
from neuroimagery.core import memory
assert memory.reset_peak()
base = memory.peak_rss_mb()
x = torch.ones(64 * 1024 * 1024 // 4 * 3)  # 192 MiB, written so it is resident
high = memory.peak_rss_mb()
del x
assert high - base > 150, (base, high)
memory.reset_peak()
assert memory.peak_rss_mb() < high - 150, (memory.peak_rss_mb(), high)  # a new phase does not inherit the old peak
assert memory.rss_mb() > 10
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the high-water mark is reset on Linux only")
def test_peak_follows_a_large_tensor_and_resets():
    """In a process started from this large one, as a run is from a shell or a sweep launcher: the
    peak restarts at a reset even though the replaced parent image was larger (``getrusage`` keeps
    that image's mark; ``VmHWM`` does not)."""
    import subprocess

    p = subprocess.run([sys.executable, "-c", PEAK_AND_RESET], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
