"""Hydra configs, validation, run outputs, checkpoints, determinism and command-line errors."""
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from hydra.errors import ConfigCompositionException

from neuroimagery.config import validate
from neuroimagery.core.errors import UserInputError
from neuroimagery.app.run import evaluate, train

from conftest import CONF, make_cfg

ROOT = Path(__file__).resolve().parents[1]


def _groups():
    for group in ("experiment", "vision", "stimuli", "logger"):
        for f in sorted((Path(CONF) / group).glob("*.yaml")):
            yield group, f.stem


@pytest.mark.parametrize("group,option", list(_groups()))
def test_every_config_group_option_composes_and_validates(group, option):
    overrides = [f"{group}={option}"]
    if group == "stimuli" and option == "folder":
        overrides.append(f"stimuli.path={ROOT}")
    cfg = validate(make_cfg(*overrides))
    assert cfg.experiment.name


def test_misspelt_key_is_rejected_while_composing():
    with pytest.raises(UserInputError, match="stp_deg"):
        validate(make_cfg("experiment=demo", "+experiment.stp_deg=3"))
    with pytest.raises(ConfigCompositionException, match="stp_deg"):
        make_cfg("experiment=demo", "experiment.stp_deg=3")


def test_wrong_type_is_rejected():
    with pytest.raises(ConfigCompositionException, match="seed"):
        make_cfg("experiment=demo", "seed=abc")


@pytest.mark.parametrize("override,key", [("participants=0", "participants"), ("experiment.eta=-1", "eta"),
                                          ("logger.kind=wandb", "logger.kind"), ("preset=huge", "preset")])
def test_out_of_range_values_name_the_key(override, key):
    with pytest.raises(UserInputError, match=key):
        validate(make_cfg("experiment=demo", override))


def _run(tmp, *over):
    return evaluate(make_cfg("experiment=demo", "participants=2", *over), out_dir=tmp)


def test_run_writes_the_results_layout(tmp_path):
    s = _run(tmp_path)
    for f in (".hydra/config.yaml", "checkpoints/model.pt", "trials.csv", "summary.json", "report.md", "figures/rt_by_disparity.png"):
        assert (tmp_path / f).exists(), f
    assert list((tmp_path / "tb").glob("events.out.tfevents.*"))
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["experiment"] == "demo" and summary["participants"] == 2
    t = summary["tests"]["rotation/none"]
    assert set(t) >= {"n_trials", "correct_rate", "error_rate", "rotation_success_rate", "rt_mean", "rt_by_disparity",
                      "error_rate_by_disparity", "rt_slope_per_deg", "rt_r"}
    rt = summary["runtime_s"]
    assert {"train", "evaluate", "figures"} <= set(rt) <= {"train", "evaluate", "figures", "startup"}
    assert 0 < rt["figures"] <= rt["evaluate"]  # the demo draws its RT figure within its evaluation
    assert set(summary["peak_rss_mb"]) == {"train", "evaluate"}
    assert all(v is None or v > 10 for v in summary["peak_rss_mb"].values())  # MiB: a Python process with torch
    df = pd.read_csv(tmp_path / "trials.csv")
    assert len(df) == t["n_trials"] == 2 * 37
    assert "rt_by_disparity.png" in (tmp_path / "report.md").read_text()
    assert s["tests"] == summary["tests"]


def test_same_seed_same_files_other_seed_other_results(tmp_path):
    _run(tmp_path / "a", "seed=3")
    _run(tmp_path / "b", "seed=3")
    _run(tmp_path / "c", "seed=4")
    read = lambda d: (tmp_path / d / "trials.csv").read_bytes()
    summ = lambda d: {k: v for k, v in json.loads((tmp_path / d / "summary.json").read_text()).items()
                    if k not in ("runtime_s", "peak_rss_mb")}  # measured: time and memory
    assert read("a") == read("b") and summ("a") == summ("b")
    assert read("a") != read("c")


def test_checkpoint_evaluation_equals_train_then_evaluate(tmp_path):
    train(make_cfg("experiment=demo", "participants=2"), out_dir=tmp_path / "train")
    _run(tmp_path / "eval", f"checkpoint={tmp_path / 'train'}")
    _run(tmp_path / "both")
    assert (tmp_path / "eval" / "trials.csv").read_bytes() == (tmp_path / "both" / "trials.csv").read_bytes()


def test_bad_checkpoint_is_a_clear_error(tmp_path):
    with pytest.raises(UserInputError, match="checkpoint"):
        _run(tmp_path / "x", f"checkpoint={tmp_path / 'missing'}")
    (tmp_path / "empty").mkdir()
    with pytest.raises(UserInputError, match="model.pt"):
        _run(tmp_path / "y", f"checkpoint={tmp_path / 'empty'}")


@pytest.mark.parametrize("args,needle", [(["participants=0"], "error: invalid configuration: participants"),
                                         (["experiment.stp_deg=1"], "stp_deg")])
def test_command_line_errors_are_one_clear_message(tmp_path, args, needle):
    p = subprocess.run([sys.executable, str(ROOT / "train.py"), "experiment=demo", f"hydra.run.dir={tmp_path}", *args],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode != 0
    assert needle in p.stderr
    assert "Traceback" not in p.stderr


def test_summary_splits_errors_into_same_and_mirror_pairs():
    from neuroimagery.analysis.summary import summarise_test

    rows = []
    for same, correct in [(True, True), (True, False), (True, False), (True, True), (False, True), (False, False)]:
        rows.append(dict(disparity=0, rt=1.0, rotated_ok=True, same=same, correct=correct))
    t = summarise_test(pd.DataFrame(rows))
    assert t["error_rate_same"] == 0.5 and t["error_rate_different"] == 0.5
    assert t["error_rate"] == round(3 / 6, 4)
    t = summarise_test(pd.DataFrame(rows[:4]))
    assert t["error_rate_same"] == 0.5 and t["error_rate_different"] is None


def test_process_age_counts_from_the_process_start():
    """runtime_s.startup: seconds from the process's start (a pause before the import included)."""
    import subprocess
    import sys

    code = ("import time; time.sleep(0.6); from neuroimagery.app.run import process_age_s; a = process_age_s(); "
            "print('none' if a is None else a)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    if out == "none":
        pytest.skip("no /proc on this platform")
    assert 0.6 <= float(out) < 60
