"""``workers.run_pieces``: the same results in the pieces' order in one process and in workers,
and a failed piece's error reaches the caller."""
import pytest

from neuroimagery.core.workers import run_pieces


@pytest.mark.parametrize("jobs", [1, 2])
def test_results_come_in_the_pieces_order(jobs):
    pieces = [(i, 2) for i in range(9, -1, -1)]
    assert run_pieces(pow, pieces, jobs, "test") == [i * i for i in range(9, -1, -1)]
    assert run_pieces(pow, [], jobs, "test") == []


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failed_piece_raises(jobs):
    with pytest.raises(ValueError, match="invalid literal"):
        run_pieces(int, [("1",), ("x",), ("3",)], jobs, "test")


def test_sigterm_is_an_interrupt_while_the_pieces_run_and_the_handler_is_restored():
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import os, signal
        from neuroimagery.core.workers import run_pieces
        try:
            run_pieces(os.kill, [(os.getpid(), signal.SIGTERM)], 1, "test")
        except KeyboardInterrupt:
            print("interrupt", signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.split() == ["interrupt", "True"], (done.returncode, done.stderr[-400:])


def test_a_worker_ends_within_a_second_of_its_parent_s_death():
    """``watch_parent`` in a child: its parent killed with SIGKILL, the child is gone within 3 s (the
    slow tests/test_kill_workers.py does the same to whole runs)."""
    import os
    import subprocess
    import sys
    import textwrap
    import time

    parent = textwrap.dedent("""
        import os, signal, subprocess, sys
        child = subprocess.Popen([sys.executable, "-c",
            "import os, time; from neuroimagery.core.workers import watch_parent; watch_parent(%d); "
            "print('ready', flush=True); time.sleep(60)" % os.getpid()], stdout=subprocess.PIPE, text=True)
        assert child.stdout.readline().strip() == "ready"
        print(child.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    done = subprocess.run([sys.executable, "-c", parent], capture_output=True, text=True, timeout=60)
    child = int(done.stdout.split()[0])
    t0 = time.monotonic()
    while time.monotonic() - t0 < 3.0:
        try:
            with open(f"/proc/{child}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    break
        except OSError:
            break
        time.sleep(0.05)
    else:
        os.kill(child, 9)
        raise AssertionError("the child outlived its parent by 3 s")


def test_the_workers_of_parallel_watch_this_process():
    import os

    from joblib import delayed

    from neuroimagery.core import workers

    def watched():
        return list(workers._WATCHED)

    assert all(w == [os.getpid()] for w in workers.parallel(2)(delayed(watched)() for _ in range(2)))
    workers.guard()  # in a process no pool started: nothing to watch
    assert workers._WATCHED == []
