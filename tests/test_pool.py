"""Pooling seeds (``python -m neuroimagery.app.pool``): the pooled rows, summary and report of demo
runs, and every refusal of runs that do not belong together, as one ``error:`` line."""
import json
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import make_cfg

from neuroimagery.app import cli, pool
from neuroimagery.core import manifest as mf
from neuroimagery.app.run import evaluate

ROOT = Path(__file__).resolve().parents[1]


def _demo(d: Path, *over: str) -> Path:
    evaluate(make_cfg("experiment=demo", "participants=2", "logger=none", *over), out_dir=d)
    return d


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """Two demo runs laid out as a Hydra sweep (``-m seed=0,1``), and one with other settings."""
    root = tmp_path_factory.mktemp("pool")
    for s in (0, 1):
        _demo(root / "sweep" / str(s), f"seed={s}")
    _demo(root / "other", "seed=2", "participants=3", "experiment.eta=0.3")
    return root


def _copy(sweep, tmp_path, name="0") -> Path:
    d = tmp_path / f"copy{name}"
    shutil.copytree(sweep / "sweep" / name, d)
    return d


def _refused(capsys, argv, *needles) -> str:
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(pool.main)(list(map(str, argv)))
    err = capsys.readouterr().err
    assert ex.value.code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def test_pooled_rows_summary_and_report(sweep, tmp_path, capsys):
    runs = [sweep / "sweep" / "0", sweep / "sweep" / "1"]
    summary, df, rep = pool.pool(runs)
    assert pool.pool([sweep / "sweep"])[0] == summary  # a sweep directory stands for its runs
    singles = [json.loads((d / "summary.json").read_text())["tests"]["rotation/none"] for d in runs]
    both = pd.concat([pd.read_csv(d / "trials.csv").assign(run=str(d), seed=s) for s, d in enumerate(runs)],
                     ignore_index=True)
    assert len(df) == len(both) == 2 * 2 * 37
    assert list(df.columns[-2:]) == ["run", "seed"] and set(df.seed) == {0, 1} and set(df.run) == set(map(str, runs))
    t = summary["tests"]["rotation/none"]
    assert t["n_trials"] == 148 and t["rt_mean"] == round(both.rt.mean(), 3)
    assert t["correct_rate"] == round(both.correct.mean(), 4)
    assert summary["seeds"] == [0, 1] and summary["participants"] == 4
    rts = [s["rt_mean"] for s in singles]
    assert rts[0] != rts[1]  # the seeds differ, so the spread below is not zero by construction
    assert t["per_seed"] == {str(k): {m: s[m] for m, _, _ in pool.MEASURES} for k, s in enumerate(singles)}
    assert t["across_seeds"]["rt_mean"]["mean"] == round(statistics.fmean(rts), 4)
    assert t["across_seeds"]["rt_mean"]["sd"] == round(statistics.stdev(rts), 4)
    assert t["across_seeds"]["error_rate_different"]["n"] == 0  # the demo has no mirror pairs
    pool.main([str(sweep / "sweep"), "--out", str(tmp_path / "out")])
    assert "pooled report:" in capsys.readouterr().out
    saved = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert saved["tests"] == summary["tests"]
    assert len(pd.read_csv(tmp_path / "out" / "trials.csv")) == len(df)
    text = (tmp_path / "out" / "report.md").read_text()
    assert "| measure | seed 0 | seed 1 | mean | SD | pooled | thesis |" in text
    assert f"| RT mean | {rts[0]:.3g} | {rts[1]:.3g} | {statistics.fmean(rts):.3g} |" in text


def test_report_puts_the_thesis_targets_beside_the_seeds(sweep, tmp_path):
    runs = [_copy(sweep, tmp_path, "0"), _copy(sweep, tmp_path, "1")]
    for d in runs:  # the demo has no thesis; give it the targets an experiment's summary carries
        s = json.loads((d / "summary.json").read_text())
        s["targets"] = {"rotation/none": {"correct_rate": 0.9, "rotation_success_A": 0.5}}
        (d / "summary.json").write_text(json.dumps(s))
        _edit_manifest(d, files={**json.loads((d / "manifest.json").read_text())["files"],
                                 "summary.json": mf.file_hash(d / "summary.json")})  # as if the run wrote it
    summary, _, rep = pool.pool(runs)
    assert summary["targets"]["rotation/none"]["correct_rate"] == 0.9
    row = next(ln for ln in rep.text().splitlines() if ln.startswith("| correct |"))
    assert row.endswith("| 90.0 % |")
    assert "rotation/none: rotation_success_A 50.0 %" in rep.text()  # a target that is not a pooled measure


def _edit_manifest(d: Path, **change) -> None:
    m = json.loads((d / "manifest.json").read_text())
    m.update(change)
    (d / "manifest.json").write_text(json.dumps(m))


def test_runs_of_another_experiment_settings_or_the_same_seed_are_refused(sweep, tmp_path, capsys):
    run0 = sweep / "sweep" / "0"
    line = _refused(capsys, [run0, sweep / "other"], "experiment.eta", "participants", "differ only in seed")
    assert "seed " not in line.split("differ only")[0]  # the seed may differ: it is not named
    _refused(capsys, [run0, _copy(sweep, tmp_path)], "both have seed 0")
    exp3 = _copy(sweep, tmp_path, "1")
    _edit_manifest(exp3, experiment="exp3")
    _refused(capsys, [run0, exp3], f"{exp3} is a run of exp3")


def _damage(d: Path, how: str) -> None:
    csv = d / "trials.csv"
    text = csv.read_text()
    lines = text.splitlines(keepends=True)
    if how == "header only":
        csv.write_text(lines[0])
    elif how == "rows cut":
        csv.write_text("".join(lines[:-3]))
    elif how == "last line cut":
        csv.write_text(text[:-5])
    elif how == "not CSV":
        csv.write_bytes(b"\x80PK\x03\x04 binary\x00\xff\n")
    elif how == "empty":
        csv.write_text("")
    elif how == "answer changed":
        csv.write_text(lines[0] + lines[1].replace(",True,yes,True,", ",True,no,False,", 1) + "".join(lines[2:]))
    elif how == "other test":
        csv.write_text(text.replace(",rotation,none,", ",rotation2,none,"))
    elif how == "column dropped":
        pd.read_csv(csv).drop(columns=["rt"]).to_csv(csv, index=False)
    elif how == "empty field":
        csv.write_text(lines[0] + lines[1].rsplit(",", 1)[0] + ",\n" + "".join(lines[2:]))


@pytest.mark.parametrize("how,why", [
    ("header only", "no rows (header only)"), ("rows cut", "has 71 rows, but summary.json counts 74"),
    ("last line cut", "cut short"), ("not CSV", "not a readable CSV file"), ("empty", "empty file"),
    ("answer changed", "correct_rate is 0.9865 from the rows, 1.0 in summary.json"),
    ("other test", "no rows of test rotation/none"), ("column dropped", "missing columns rt"),
    ("empty field", "line 2 has empty fields"),
])
def test_rows_that_are_not_the_summary_s_are_refused(sweep, tmp_path, capsys, how, why):
    d = _copy(sweep, tmp_path, "1")
    _damage(d, how)
    _refused(capsys, [sweep / "sweep" / "0", d], f"{d / 'trials.csv'}: ", why)


def test_what_is_not_a_finished_run_is_refused(sweep, tmp_path, capsys):
    run0 = sweep / "sweep" / "0"
    _refused(capsys, [run0, tmp_path / "nowhere"], "no such run directory")
    old = _copy(sweep, tmp_path, "1")
    (old / "manifest.json").unlink()  # a run directory without a manifest, as 0.1.0 left it
    line = _refused(capsys, [run0, old], f"pool: {old} is a run of neuroimagery 0.1.0 (no manifest.json)")
    assert line.endswith("run it again: python evaluate.py experiment=demo seed=1")
    shutil.rmtree(old / ".hydra")
    _refused(capsys, [run0, old], f"{old}: not a finished run directory")
    (old / "manifest.json").write_text("{cut")
    _refused(capsys, [run0, old], f"{old / 'manifest.json'}: cannot be read")
    (old / "manifest.json").write_text(json.dumps({"experiment": "demo", "seed": 1}))
    _refused(capsys, [run0, old], "no 'settings'")
    stopped = _copy(sweep, tmp_path, "0")
    (stopped / "summary.json").unlink()
    _refused(capsys, [stopped], f"{stopped}: no summary.json (not a finished run")
    _refused(capsys, [run0, "--out", sweep / "sweep" / "1"], "is a run directory")


def test_a_run_of_a_0x_release_is_refused_naming_its_version_and_the_command(sweep, tmp_path, capsys, monkeypatch):
    import neuroimagery

    old = _copy(sweep, tmp_path, "1")
    m = json.loads((old / "manifest.json").read_text())
    (old / "manifest.json").write_text(json.dumps({**m, "package": "0.2.0"}))
    monkeypatch.setattr(neuroimagery, "__version__", "1.0.0")
    line = _refused(capsys, [old], f"pool: {old} is a run of neuroimagery 0.2.0, which 1.0.0 does not read")
    assert line.endswith("run it again: python evaluate.py experiment=demo seed=1")
    monkeypatch.setattr(neuroimagery, "__version__", "0.9.0")  # a run of the same major release is pooled
    summary, _, _ = pool.pool([sweep / "sweep" / "0", old])
    assert summary["seeds"] == [0, 1]


def test_the_command_runs_as_a_module(sweep, tmp_path):
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "neuroimagery.app.pool", str(sweep / "sweep"), "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "# Demo pooled over 2 runs" in p.stdout and (out / "trials.csv").is_file()
    p = subprocess.run([sys.executable, "-m", "neuroimagery.app.pool", str(sweep / "sweep" / "0"), str(sweep / "other")],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 2 and p.stderr.startswith("error: pool: runs with other settings") and p.stderr.count("\n") == 1


def test_pooled_effects_count_each_participant_of_each_seed_once():
    import numpy as np

    rng = np.random.default_rng(0)
    rows = [{"seed": s, "participant": p, "test": t, "condition": "none", "disparity": d,
             "rt": d / 45 + rng.normal(0, 0.3), "correct": bool(rng.random() < 0.8)}
            for s in (0, 1) for p in range(3) for t in ("recog", "gen1", "gen2") for d in (0, 45, 90, 135)]
    eff = pool.pooled_effects("exp3", pd.DataFrame(rows))
    assert eff and all(e["n"] == 6 for e in eff)  # 2 seeds x 3 participants, not 3 shared ids
    slope = next(e for e in eff if e["effect"] == "recog: RT rises with disparity")
    assert slope["value"] > 0 and slope["holds"]
    assert pool.pooled_effects("demo", pd.DataFrame(rows)) == []
