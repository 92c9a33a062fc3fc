"""Shared fixtures: compose the real Hydra config and shrink it. How the suite spreads over the
cores (pytest-xdist): see :func:`pytest_cmdline_main`."""
from __future__ import annotations

import os

# OpenMP's waiting threads spin on their core by default (GNU OpenMP): in a test at two threads
# while another worker or job keeps a core busy, every parallel region then waits for a thread that
# is not running (an Exp 4 training at two threads: 60-80 s instead of 10 s on a busy machine). They
# sleep instead; set before torch loads OpenMP, and inherited by the workers and the runs tests start.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import re  # noqa: E402
from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
import torch  # noqa: E402
from hydra import compose, initialize_config_dir  # noqa: E402

from neuroimagery.config import register_configs  # noqa: E402

CONF = str(Path(__file__).resolve().parents[1] / "conf")
register_configs()
torch.set_num_threads(1)  # small tensors: one thread avoids OpenMP spin-waits on a busy machine


# ------------------------------------------------------------------ the suite on several cores
MAX_WORKERS = 4  # -n auto: a worker holds up to about 2 GB (Exp 2's full-size model is 465 MB a copy)
# files that share one process-wide trained model (tests/contracts/conftest.py, tests/support_exp6.py):
# one worker runs each group, so each model is trained once
SHARED_MODELS = re.compile(r"(?:^|/)contracts/test_(exp[346])_")


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """The whole suite (no file or test named: ``make test``, ``pytest``) runs on the free cores,
    ``-n auto --dist loadfile``, unless ``-n`` or ``--dist`` say otherwise; named files or tests run
    in this process (``-n 2`` spreads them too). ``-n 0`` or ``-p no:xdist`` keep the whole suite in
    one process. ``loadfile``: each file's tests run in one worker, in order, so a module
    fixture (a trained model, a finished run) is made once, not once per worker."""
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return
    if config.option.numprocesses is None and config.args_source == pytest.Config.ArgsSource.TESTPATHS:
        config.option.numprocesses = "auto"
    if config.option.numprocesses and config.option.dist == "no":
        config.option.dist = "loadfile"


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per core this process may run on (not psutil's count of physical
    cores, one on many two-vCPU machines), at most ``MAX_WORKERS``; one core: no workers.
    ``PYTEST_XDIST_AUTO_NUM_WORKERS=N`` sets the number."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # pytest-xdist's own hook reads it
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return min(cores, MAX_WORKERS) if cores > 1 else 0


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the files of ``SHARED_MODELS`` kept together, group by group."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SharedModels(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = super()._split_scope(nodeid)
            shared = SHARED_MODELS.search(path)
            return f"contracts {shared.group(1)}" if shared else path

    return SharedModels(config, log)


def make_cfg(*overrides: str):
    """Compose ``conf/config.yaml`` with ``overrides`` (what ``python train.py ...`` would see)."""
    with initialize_config_dir(config_dir=CONF, version_base="1.3"):
        return compose("config", overrides=list(overrides))


@pytest.fixture
def cfg_factory():
    return make_cfg


_CHECKED: dict[str, int] = {}  # report.md files already checked: path -> mtime (ns)


@pytest.fixture(autouse=True)
def reports_render(request):
    """Every ``report.md`` a test writes under pytest's temporary directories (a run's, a user
    folder's, a pool's) passes the Markdown check of ``support_markdown`` when the test ends."""
    yield
    if not {"tmp_path", "tmp_path_factory", "tmpdir"} & set(request.fixturenames):
        return
    import os

    from support_markdown import check_report

    for root, _, files in os.walk(request.getfixturevalue("tmp_path_factory").getbasetemp()):
        if "report.md" in files:
            path = os.path.join(root, "report.md")
            try:
                mtime = os.stat(path).st_mtime_ns
            except OSError:
                continue
            if _CHECKED.get(path) != mtime:
                _CHECKED[path] = mtime
                check_report(Path(path))


@pytest.fixture(autouse=True)
def progress_misses(monkeypatch):
    """Every run a test makes counts exactly the trials its test phase announced
    (``progress.expect``): a phase closing with another count fails the test. A test that misses
    on purpose empties the list this fixture yields."""
    from neuroimagery.core import progress

    missed: list[str] = []
    close = progress._Phase.close

    def checked_close(self, stopped=None):
        total = None if self.counter is None else self.counter.total
        if stopped is None and total is not None and total != self.counted:  # a phase that stopped counts fewer
            missed.append(f"{self.label}: counted {self.counted} of {total}")
        close(self, stopped)

    monkeypatch.setattr(progress._Phase, "close", checked_close)
    yield missed
    assert missed == [], missed

