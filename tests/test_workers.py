"""``workers.run_pieces``: the same results in the pieces' order in one process and in workers,
and a failed piece's error reaches the caller."""
import pytest

from neuroimagery.workers import run_pieces


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
        from neuroimagery.workers import run_pieces
        try:
            run_pieces(os.kill, [(os.getpid(), signal.SIGTERM)], 1, "test")
        except KeyboardInterrupt:
            print("interrupt", signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.split() == ["interrupt", "True"], (done.returncode, done.stderr[-400:])
