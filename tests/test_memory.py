"""The peak resident memory a run reports (neuroimagery/memory.py)."""
import sys

import pytest
import torch

from neuroimagery import memory


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the high-water mark is reset on Linux only")
def test_peak_follows_a_large_tensor_and_resets():
    assert memory.reset_peak()
    base = memory.peak_rss_mb()
    x = torch.ones(64 * 1024 * 1024 // 4 * 3)  # 192 MiB, written so it is resident
    high = memory.peak_rss_mb()
    del x
    assert high - base > 150
    memory.reset_peak()
    assert memory.peak_rss_mb() < high - 150  # a new phase does not inherit the old peak
    assert memory.rss_mb() > 10
