"""``python -m neuroimagery.robot.babble``: every bad argument is the one ``error:`` line (exit 2)
of every tool, before any rollout; counts have a bound that ``--allow-large`` lifts."""
from __future__ import annotations

import pytest

from neuroimagery.robot import babble

from support_bad_inputs import refused

CASES = [
    (["--rollouts", "abc"], "--rollouts", "not a whole number: 'abc'"),
    (["--rollouts", "2.5"], "--rollouts", "2.5"),
    (["--rollouts", "nan"], "--rollouts", "nan"),
    (["--rollouts", "inf"], "--rollouts", "inf"),
    (["--rollouts", "1e9"], "--rollouts 1000000000", "--allow-large"),
    (["--rollouts", "1000000000"], "--rollouts 1000000000", "at most 100000"),
    (["--rollouts", "0"], "--rollouts must be >= 1", None),
    (["--rollouts", "-3"], "--rollouts must be >= 1", None),
    (["--seeds", "abc"], "--seeds", None),
    (["--seeds", "0"], "--seeds must be >= 1", None),
    (["--seeds", "1000"], "--seeds 1000", "--allow-large"),
    ([], "--out", "required"),
    (["--bogus", "1"], "unrecognized arguments: --bogus 1", None),
    (["--rollouts"], "--rollouts", "expected one argument"),
]


@pytest.mark.parametrize("args,needle,also", CASES, ids=[" ".join(a) or "no --out" for a, _, _ in CASES])
def test_bad_arguments_are_one_error_line_before_any_rollout(tmp_path, capsys, monkeypatch, args, needle, also):
    def no_rollouts(*a, **k):
        raise AssertionError("babbling started before the arguments were checked")

    monkeypatch.setattr(babble, "measure", no_rollouts)
    argv = args + (["--out", str(tmp_path / "o")] if args else [])  # no arguments at all: --out is missing
    refused(capsys, lambda: babble.main(argv), needle, *([also] if also else []))


def test_counts_may_be_written_as_powers_of_ten():
    assert babble.parse(["--rollouts", "1e3", "--seeds", "2", "--out", "x"]).rollouts == 1000
    assert babble.parse(["--rollouts", "1_000_000", "--allow-large", "--out", "x"]).rollouts == 1_000_000


WORLD_CASES = [
    (["--libraries", "abc"], "--libraries", "not a whole number: 'abc'"),
    (["--libraries", "0"], "--libraries must be >= 1", None),
    (["--jobs", "0"], "--jobs must be >= 1", None),
    (["--bogus", "1"], "unrecognized arguments: --bogus 1", None),
]


@pytest.mark.parametrize("args,needle,also", WORLD_CASES, ids=[" ".join(a) for a, _, _ in WORLD_CASES])
def test_world_check_arguments_are_one_error_line_before_any_library(tmp_path, capsys, monkeypatch, args, needle, also):
    """``python -m neuroimagery.experiments.exp5.world`` parses as babble does (one ``error:`` line)."""
    from neuroimagery.experiments.exp5 import world as exp5_world

    def no_library(*a, **k):
        raise AssertionError("a library was acquired before the arguments were checked")

    monkeypatch.setattr(exp5_world, "_one_library", no_library)
    refused(capsys, lambda: exp5_world.main(args + ["--out", str(tmp_path / "o")]), needle, *([also] if also else []))
