"""threads=0 leaves out the cores other work keeps busy (measured at start-up)."""
import pytest

from neuroimagery.core import threads


@pytest.mark.parametrize("n,busy,expected", [(2, 0.0, 2), (2, 0.3, 2), (2, 1.0, 1), (2, 1.9, 1), (2, None, 2),
                                             (8, 3.2, 5), (8, 8.0, 1)])
def test_auto_threads_leaves_the_busy_cores_out(monkeypatch, n, busy, expected):
    monkeypatch.setattr(threads, "cores", lambda: n)
    monkeypatch.setattr(threads, "busy_cores", lambda sample_s=0.1: busy)
    assert threads.auto_threads() == expected


def test_busy_cores_reads_this_machine():
    b = threads.busy_cores(0.05)
    assert b is None or 0.0 <= b <= (threads.os.cpu_count() or 1) + 1e-9
