"""Sizes a setting implies, checked before any allocation: the memory estimate of each experiment
against the memory this process may use, threads against its cores, the declared bounds of the
configuration fields; ``allow_large=true`` skips the resource checks (neuroimagery.core.resources,
neuroimagery.core.bounds)."""
from __future__ import annotations

from dataclasses import dataclass

import pytest

from neuroimagery.core import resources
from neuroimagery.core.bounds import bounded, check_declared
from neuroimagery.core.errors import UserInputError

from support_bad_inputs import evaluating, no_training, refused  # noqa: F401 (fixture)

GIB = 1024 ** 3


@pytest.fixture
def small_machine(monkeypatch):
    """A process allowed 8 GiB and 2 cores, whatever this machine has."""
    monkeypatch.setattr(resources, "memory_limits", lambda: {"cgroup memory.max": 8 * GIB, "MemAvailable": 20 * GIB})
    monkeypatch.setattr(resources, "core_limits", lambda: {"CPU affinity": 4, "cgroup cpu.max": 2})


SIZE_CASES = [  # the cases of the issue, then their neighbours
    (["experiment=exp3", "preset=quick", "experiment.map_size=2048"], "experiment.map_size=2048"),
    (["experiment=exp4", "preset=quick", "experiment.map_size=512"], "experiment.map_size=512"),
    (["experiment=exp4", "preset=quick", "experiment.quick.fm_images=100000000"], "experiment.quick.fm_images=100000000"),
    (["experiment=exp3", "experiment.fm.images=100000000"], "experiment.fm.images=100000000"),
    (["experiment=exp4", "preset=quick", "participants=10000000"], "participants=10000000"),
    (["experiment=exp3", "participants=100000"], "participants=100000"),
    (["experiment=exp6", "preset=quick", "participants=1", "experiment.grid=400"], "experiment.grid=400"),
    (["experiment=exp6", "participants=1", "experiment.objects.test=10000000"], "experiment.objects.test=10000000"),
    (["experiment=exp6", "preset=quick", "participants=1", "experiment.quick.chains=1000000000"],
     "experiment.quick.chains=1000000000"),
    (["experiment=exp6", "participants=1", "experiment.fm.memory_mb=100000"], "experiment.fm.memory_mb=100000"),
    (["experiment=exp6", "participants=100000", "preset=quick", "experiment.quick.participants=100000"],
     "participants=100000"),
    (["experiment=exp2", "participants=50"], "participants=50"),  # about 230 MB of weights each
    (["experiment=exp1", "participants=500"], "participants=500"),
    (["experiment=demo", "participants=1000000000"], "participants=1000000000"),
]


@pytest.mark.parametrize("over,needle", SIZE_CASES, ids=[" ".join(o) for o, _ in SIZE_CASES])
def test_sizes_that_cannot_fit_are_refused_before_allocation(tmp_path, capsys, no_training, small_machine, over, needle):
    line = refused(capsys, evaluating(tmp_path / "run", *over), needle, "of memory", "8 GiB", "cgroup memory.max",
                   "allow_large=true")
    assert not (tmp_path / "run").exists()
    assert "B" in line.split("needs about ")[1].split(" of memory")[0]  # the estimate is named


@pytest.mark.parametrize("threads,needle", [(1000, "threads=1000"), (3, "threads=3")])
def test_threads_beyond_the_cores_this_process_may_use_are_refused(tmp_path, capsys, no_training, small_machine,
                                                                  threads, needle):
    refused(capsys, evaluating(tmp_path / "run", "experiment=demo", f"threads={threads}"), needle, "2 core(s)",
            "cgroup cpu.max")


def test_allow_large_skips_the_resource_checks(tmp_path, capsys, no_training, small_machine):
    with pytest.raises(AssertionError, match="training started"):  # the checks passed: training was reached
        evaluating(tmp_path / "run", "experiment=exp3", "preset=quick", "participants=100000", "allow_large=true")()


def test_a_run_that_fits_is_not_refused(tmp_path, no_training, small_machine):
    for over in (["experiment=exp3", "preset=quick"], ["experiment=exp4"], ["experiment=exp6", "preset=quick"],
                 ["experiment=demo", "threads=2"]):
        with pytest.raises(AssertionError, match="training started"):
            evaluating(tmp_path / "_".join(over).replace("=", ""), *over)()


def test_memory_limits_read_cgroup_rlimit_and_slurm(monkeypatch):
    monkeypatch.setenv("SLURM_MEM_PER_NODE", "1024")
    limits = resources.memory_limits()
    assert limits["SLURM_MEM_PER_NODE"] == 1024 ** 3
    assert resources.memory_limit()[0] <= 1024 ** 3
    monkeypatch.delenv("SLURM_MEM_PER_NODE")
    monkeypatch.setenv("SLURM_MEM_PER_CPU", "100")
    monkeypatch.setenv("SLURM_CPUS_PER_TASK", "3")
    assert resources.memory_limits()["SLURM_MEM_PER_CPU"] == 300 * 1024 ** 2
    assert resources.core_limits()["SLURM_CPUS_PER_TASK"] == 3
    assert resources.core_limit()[0] <= 3


def test_cgroup_v2_limits_are_read(monkeypatch, tmp_path):
    (tmp_path / "cgroup.controllers").write_text("cpu memory")
    (tmp_path / "memory.max").write_text(str(3 * GIB))
    (tmp_path / "memory.current").write_text(str(GIB))
    (tmp_path / "cpu.max").write_text("150000 100000")
    monkeypatch.setattr(resources, "CGROUP", tmp_path)
    monkeypatch.setattr(resources, "_own_cgroup", lambda: tmp_path)
    assert resources.memory_limits()["cgroup memory.max"] == 2 * GIB
    assert resources.core_limits()["cgroup cpu.max"] == 2


def test_the_estimate_names_the_setting_furthest_above_its_default():
    assert resources.culprit({"participants": (10, 10), "experiment.map_size": (2048, 32)}) == "experiment.map_size=2048"
    assert resources.culprit({"participants": (10 ** 7, 10), "experiment.map_size": (32, 32)}) == "participants=10000000"


@dataclass
class _Group:
    rate: float = bounded(0.1, gt=0, le=1)
    steps: int = bounded(5, ge=1)
    mode: str = bounded("a", choices=("a", "b"))
    ages: list = bounded(factory=lambda: [1, 2], ge=0, each=True, nonempty=True)
    free: float = 3.0

    def __post_init__(self):
        check_declared(self, "experiment.group.")


@pytest.mark.parametrize("kw,needle", [
    ({"rate": 0.0}, "experiment.group.rate must be in (0, 1], got 0.0"),
    ({"rate": 1.5}, "experiment.group.rate must be in (0, 1]"),
    ({"rate": float("nan")}, "experiment.group.rate"),
    ({"steps": 0}, "experiment.group.steps must be >= 1, got 0"),
    ({"steps": "x"}, "experiment.group.steps"),
    ({"mode": "c"}, "experiment.group.mode must be one of 'a', 'b', got 'c'"),
    ({"ages": [1, -5]}, "experiment.group.ages[1] must be >= 0, got -5"),
    ({"ages": []}, "experiment.group.ages must not be empty"),
])
def test_declared_bounds_are_checked_generically(kw, needle):
    with pytest.raises(UserInputError) as ex:
        _Group(**kw)
    assert needle in str(ex.value)


def test_fields_without_bounds_are_left_alone():
    assert _Group(free=-1e9).free == -1e9
