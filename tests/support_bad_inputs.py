"""Helpers of the bad-input tables (tests/test_bad_inputs*.py): run a command as the command line
would, in-process, and check that it was refused with one ``error:`` line naming the culprit,
exit status 2, no traceback, within seconds, before any training."""
from __future__ import annotations

import time

import pytest

from neuroimagery.app import cli
from neuroimagery.app.run import evaluate, train

from conftest import make_cfg
from support_experiments import patch_experiment

from neuroimagery.config import EXPERIMENTS  # noqa: E402
LIMIT_S = 10.0  # a refusal must come within seconds: these are checks, not work


@pytest.fixture
def no_training(monkeypatch):
    """Any experiment that starts training fails the test: refusals must come first."""
    def forbidden(*a, **k):
        raise AssertionError("training started before the input was refused")

    for name in EXPERIMENTS:
        patch_experiment(monkeypatch, name, train=forbidden)


def refused(capsys, fn, *needles, code: int = 2) -> str:
    """Run ``fn`` (which exits, or returns an exit status); assert one clear ``error:`` line naming ``needles``."""
    t0 = time.perf_counter()
    try:
        status = fn()
    except SystemExit as ex:
        status = ex.code
    took = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert status == code, err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, err
    assert [ln for ln in err.splitlines() if ln.strip()] == lines, err  # nothing else on stderr
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert took < LIMIT_S, f"refused after {took:.1f} s"
    return lines[0]


def evaluating(tmp, *over):
    return lambda: cli.friendly_errors(evaluate)(make_cfg(*over), out_dir=tmp)


def training(tmp, *over):
    return lambda: cli.friendly_errors(train)(make_cfg(*over), out_dir=tmp)


def composing(*over):
    """Hydra's composition of ``over`` through the command line's reporter."""
    from hydra._internal import utils as hydra_utils

    return lambda: hydra_utils.run_and_report(lambda: make_cfg(*over))


@pytest.fixture
def hydra_reporter(monkeypatch):
    """The command line's reporter of Hydra's refusals (and its refusal of empty and deleted
    overrides), put back as it was afterwards."""
    from hydra._internal import utils as hydra_utils
    from hydra.core.override_parser.overrides_parser import OverridesParser

    monkeypatch.setattr(hydra_utils, "run_and_report", hydra_utils.run_and_report)
    monkeypatch.setattr(OverridesParser, "parse_overrides", OverridesParser.parse_overrides)
    cli.plain_hydra_errors()
