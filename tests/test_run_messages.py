"""What a run shows: its lines on the terminal and in Hydra's job log, one plain ``error:`` line for a
refusal, progress bars of Experiments 1-4 on stderr unless ``progress=false``."""
import json
import logging
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from conftest import make_cfg
from support_runs import rehash

from neuroimagery.app import cli
from neuroimagery.app.run import evaluate, train

ROOT = Path(__file__).resolve().parents[1]


def _evaluate_py(run_dir: Path, *args: str):
    return subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "experiment=demo", "logger=none",
                           f"hydra.run.dir={run_dir}", *args], capture_output=True, text=True, cwd=ROOT, timeout=180)


def test_the_job_log_holds_what_the_run_printed_and_a_refusal_is_one_plain_line(tmp_path):
    run = tmp_path / "run"
    p = _evaluate_py(run, "participants=2")
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines() == [f"report: {run}/report.md"]  # no logging prefix on the terminal
    log = (run / "evaluate.log").read_text()
    assert f"[neuroimagery][INFO] - report: {run}/report.md" in log
    p = _evaluate_py(run, "participants=3")  # the directory holds a run with other settings
    assert p.returncode == 2
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: {run} holds another run (participants 2"), p.stderr
    assert "error" not in p.stdout
    assert (run / "evaluate.log").read_text() == log  # a refused run writes nothing into another run's directory


def test_notes_go_to_stderr_and_to_the_neuroimagery_logger(tmp_path, capsys, caplog):
    cfg = make_cfg("experiment=demo", "participants=2", "logger=none")
    evaluate(cfg, out_dir=tmp_path)
    capsys.readouterr()
    with caplog.at_level(logging.INFO, logger="neuroimagery"):
        evaluate(cfg, out_dir=tmp_path)
    err = capsys.readouterr().err
    note = f"note: {tmp_path} holds a run with the same settings: rewriting it"
    assert err.splitlines() == [note]
    assert [(r.name, r.levelname, r.getMessage()) for r in caplog.records] == [("neuroimagery", "WARNING", note)]


def test_an_error_line_is_logged_without_a_second_line_on_stderr(tmp_path, capsys, caplog):
    with caplog.at_level(logging.INFO, logger="neuroimagery"), pytest.raises(SystemExit):
        cli.friendly_errors(evaluate)(make_cfg("experiment=demo", f"checkpoint={tmp_path / 'none'}"), out_dir=tmp_path / "r")
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("error: checkpoint:")
    assert [r.getMessage() for r in caplog.records] == [err.strip()]


QUICK = ("preset=quick", "participants=1", "logger=none", "experiment.quick.fm_images=300",
         "experiment.posture.iterations=100", "experiment.selection.max_steps=3", "experiment.percept.looks=2")


def test_a_quick_run_shows_training_and_test_bars_and_progress_false_none(tmp_path, capsys, caplog):
    """The bars and their counts do not depend on how long a trial runs or how many looks each item
    has: the runs stop a trial after 3 rotation steps and build 2 looks per item (the same 2160
    trials, in about half the time)."""
    with caplog.at_level(logging.INFO, logger="neuroimagery"):
        evaluate(make_cfg(*QUICK), out_dir=tmp_path / "bars")  # the default experiment, exp4
    err = capsys.readouterr().err
    for bar in ("exp4 train: forward model: 100%", "exp4 train: posture maps: 100%", "13/13", "2/2"):
        assert bar in err, bar
    shown = err.replace("\r", "\n").split("exp4 test: ")
    assert any(b.startswith("  0%|") and "| 0/2160 " in b for b in shown)  # the total before the first block
    last = shown[-1]
    assert last.startswith("100%|") and "| 2160/2160 [" in last and "<00:00" in last  # every trial counted, an ETA
    assert "gen2/mismatch" in last  # the last block named
    logged = [r.getMessage() for r in caplog.records]
    assert not any("announced" in m for m in logged)
    assert any(m.startswith("exp4 train: done in") for m in logged)
    assert any(m.startswith("exp4 test: 2160 trials done in") for m in logged)
    # fewer trials: whether bars are drawn does not depend on how many
    evaluate(make_cfg(*QUICK, "progress=false", "experiment.noise_tests=[]"),
             out_dir=tmp_path / "quiet")
    err = capsys.readouterr().err
    assert (tmp_path / "quiet" / "trials.csv").is_file()  # it trained and tested
    assert "exp4 train" not in err and "exp4 test" not in err and "%|" not in err


def test_a_run_or_checkpoint_of_another_version_says_which(tmp_path, capsys):
    cfg = lambda *o: make_cfg("experiment=demo", "participants=2", "logger=none", *o)  # noqa: E731
    train(cfg(), out_dir=tmp_path / "tr")
    manifest = json.loads((tmp_path / "tr" / "manifest.json").read_text())
    ck = tmp_path / "tr" / "checkpoints" / "model.pt"
    state = torch.load(ck, weights_only=True)
    torch.save({**state, "manifest": {**state["manifest"], "package": "1.9.9"}}, ck)
    rehash(tmp_path / "tr")  # as that version's run would have recorded it
    evaluate(cfg(f"checkpoint={tmp_path / 'tr'}"), out_dir=tmp_path / "ev")
    assert f"note: checkpoint {ck} was written by version 1.9.9 (this is {manifest['package']})" in capsys.readouterr().err
    (tmp_path / "ev" / "manifest.json").write_text(json.dumps({**manifest, "package": "1.9.9"}))
    evaluate(cfg(f"checkpoint={tmp_path / 'tr'}"), out_dir=tmp_path / "ev")
    assert f"note: {tmp_path / 'ev'} holds a run of version 1.9.9" in capsys.readouterr().err
    torch.save({k: v for k, v in state.items() if k != "manifest"}, ck)  # as version 0.1.0 wrote it
    rehash(tmp_path / "tr")
    with pytest.raises(SystemExit):
        cli.friendly_errors(evaluate)(cfg(f"checkpoint={tmp_path / 'tr'}"), out_dir=tmp_path / "ev2")
    assert "has no manifest (written by neuroimagery 0.1.0" in capsys.readouterr().err
    (tmp_path / "tr" / "manifest.json").unlink()
    with pytest.raises(SystemExit):
        cli.friendly_errors(train)(cfg(), out_dir=tmp_path / "tr")
    assert "holds a run without a manifest (train.json, model.pt; a run of version 0.1.0" in capsys.readouterr().err


def test_the_test_bar_has_a_total_and_says_when_the_count_misses_it(capsys, caplog, progress_misses):
    from neuroimagery.core import progress

    with caplog.at_level(logging.INFO, logger="neuroimagery"):
        with progress.phase("exp9 test", True):
            progress.expect(10)
            progress.advance(4, note="a/none")
            progress.advance(6, note="b/none")
        with progress.phase("exp9 test", False):
            progress.expect(10)
            progress.advance(4)
    err = capsys.readouterr().err.replace("\r", "\n")
    assert "| 0/10 [" in err and "| 10/10 [" in err and "0 trials [" not in err
    logged = [r.getMessage() for r in caplog.records]
    assert logged[0].startswith("exp9 test: 10 trials done in")
    assert logged[-1] == "exp9 test: counted 4 of the 10 trials announced"
    assert progress_misses == ["exp9 test: counted 4 of 10"]
    progress_misses.clear()  # missed on purpose


def _entry(*args: str):
    return subprocess.run([sys.executable, str(ROOT / "evaluate.py"), *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=180)


def test_help_names_the_experiments_and_explains_the_top_level_keys():
    from neuroimagery.config import EXPERIMENTS, Config

    p = _entry("--help")
    assert p.returncode == 0, p.stderr
    head = p.stdout.split("== Every setting")[0]
    assert "_schema" not in head
    for name in EXPERIMENTS:
        assert name in head, name
    for key in ("seed", "participants", "preset", "checkpoint", "threads", "progress", "overwrite", "allow_large"):
        assert f"  {key}=" in head, key
    assert set(Config.__dataclass_fields__) - {"experiment", "vision", "stimuli", "logger"} <= \
        {k.split("=")[0].strip() for k in head.splitlines() if "=" in k}


@pytest.mark.parametrize("arg, line", [
    ("experment=exp4", "error: experment is not a setting (did you mean experiment?)"),
    ("experiment=exp7", "error: experiment=exp7 is not an option of experiment: choose one of demo, exp1, exp2, "
                        "exp3, exp4, exp5, exp6"),
    ("seed=-1", "error: invalid configuration: seed must be in [0, 9223372036854775808), got -1"),
])
def test_a_refused_top_level_setting_is_one_plain_line(arg, line, tmp_path):
    p = _entry(arg, f"hydra.run.dir={tmp_path / 'r'}")  # not under the repository's outputs/
    assert p.returncode == 2
    assert [ln for ln in p.stderr.splitlines() if ln.strip()] == [line]
