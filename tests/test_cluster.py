"""Sweeps through Hydra's submitit launcher: the presets in conf/hydra/launcher, a real two-job sweep
on submitit's local executor pooled with neuroimagery.app.pool, and a refused job as one error line."""
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra_plugins.hydra_submitit_launcher import config as submitit_launcher  # the cluster extra, in .[test]
from omegaconf import OmegaConf

from conftest import CONF
from neuroimagery.app import cli, pool

ROOT = Path(__file__).resolve().parents[1]


def _launcher(name: str) -> dict:
    with initialize_config_dir(config_dir=CONF, version_base="1.3"):
        cfg = compose("config", overrides=["experiment=demo", f"hydra/launcher={name}"], return_hydra_config=True)
    return OmegaConf.to_container(cfg.hydra.launcher)


@pytest.mark.parametrize("name,schema", [("submitit_slurm", "SlurmQueueConf"), ("submitit_local", "LocalQueueConf")])
def test_the_presets_set_every_key_of_the_plugin(name, schema):
    ours = _launcher(name)
    fields = {f.name for f in dataclasses.fields(getattr(submitit_launcher, schema))}
    assert set(ours) == fields  # nothing left to the plugin, nothing it does not know
    OmegaConf.merge(OmegaConf.structured(getattr(submitit_launcher, schema)), ours)  # of the plugin's types
    if name == "submitit_slurm":
        assert (ours["partition"], ours["tasks_per_node"], ours["cpus_per_task"], ours["timeout_min"]) == (None, 1, 2, 60)
        assert ours["_target_"].endswith("SlurmLauncher")
    else:
        assert ours["_target_"].endswith("LocalLauncher")


def test_a_two_job_sweep_on_the_local_executor_pools(tmp_path):
    sweep = tmp_path / "sweep"
    p = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "-m", "experiment=demo", "participants=2", "seed=0,1",
                        "logger=none", "hydra/launcher=submitit_local", f"hydra.sweep.dir={sweep}"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "Warning" not in p.stderr, p.stderr
    assert list((sweep / ".submitit").iterdir())  # the jobs went through submitit
    for job in ("0", "1"):
        assert f"report: {sweep / job}/report.md" in (sweep / job / "evaluate.log").read_text()
    summary, df, _ = pool.pool([sweep])
    assert summary["seeds"] == [0, 1] and summary["participants"] == 4 and len(df) == 2 * 2 * 37
    assert [r["run"] for r in summary["runs"]] == [str(sweep / "0"), str(sweep / "1")]


def test_a_refused_sweep_job_is_one_error_line(capsys):
    from submitit.core.utils import UncompletedJobError

    ex = UncompletedJobError("Job 16291 (task: 0) with path /s/.submitit/16291/16291_0_result.pkl\nhas not produced "
                             "any output (state: FINISHED)\nError stream produced:\n----\n<frozen runpy>:88: UserWarning:\n"
                             "error: /s/0 holds another run (participants 2 (stored) vs 3 (this run)): choose another")
    assert cli._refused_sweep_job(ex) == ("a job of the sweep stopped: /s/0 holds another run (participants 2 (stored) "
                                          "vs 3 (this run)): choose another (the job's output: /s/.submitit/16291)")
    assert cli._refused_sweep_job(UncompletedJobError("Job 1 ... Traceback (most recent call last): ...")) is None
    assert cli._refused_sweep_job(ValueError("error: not from a job")) is None
