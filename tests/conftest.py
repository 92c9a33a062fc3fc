"""Shared fixtures: compose the real Hydra config and shrink it."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs

CONF = str(Path(__file__).resolve().parents[1] / "conf")
register_configs()
torch.set_num_threads(1)  # small tensors: one thread avoids OpenMP spin-waits on a busy machine


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

