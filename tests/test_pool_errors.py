"""``python -m neuroimagery.app.pool``: each input it cannot pool is one ``error:`` line naming the file
(manifests without the fields a run writes, saved configurations that are malformed, tagged or
unresolvable, an ``--out`` that cannot be written); nothing in a file is run."""
import json
import shutil
from pathlib import Path

import pytest
from conftest import make_cfg

from neuroimagery.app import cli, pool
from neuroimagery.experiments.exp5 import pool as exp5_pool
from neuroimagery.app.run import evaluate


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("poolerr")
    for s in (0, 1):
        evaluate(make_cfg("experiment=demo", "participants=2", "progress=false", "logger=none", f"seed={s}"),
                 out_dir=root / f"s{s}")
    return root


def _refused(capsys, argv) -> str:
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(pool.main)([str(a) for a in argv])
    err = capsys.readouterr().err
    assert ex.value.code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("key", ["participants", "experiment", "seed", "settings"])
def test_a_manifest_without_a_field_is_one_line(runs, tmp_path, capsys, key):
    d = tmp_path / "r"
    shutil.copytree(runs / "s1", d)
    m = json.loads((d / "manifest.json").read_text())
    m.pop(key)
    (d / "manifest.json").write_text(json.dumps(m))
    assert f"{d / 'manifest.json'}: no {key!r}" in _refused(capsys, [runs / "s0", d])


def test_a_manifest_whose_settings_are_not_a_mapping_is_one_line(runs, tmp_path, capsys):
    d = tmp_path / "r"
    shutil.copytree(runs / "s1", d)
    m = json.loads((d / "manifest.json").read_text())
    (d / "manifest.json").write_text(json.dumps({**m, "settings": [1, 2]}))
    assert "'settings' is not a mapping" in _refused(capsys, [runs / "s0", d])


@pytest.mark.parametrize("out,why", [("file", "is a file, not a folder"), ("under-file", "cannot write into"),
                                     ("run", "is a run directory")])
def test_an_out_that_cannot_be_written_is_refused_before_pooling(runs, tmp_path, capsys, monkeypatch, out, why):
    f = tmp_path / "afile"
    f.write_text("x")
    target = {"file": f, "under-file": f / "sub", "run": runs / "s1"}[out]
    monkeypatch.setattr(pool, "pool", lambda dirs: pytest.fail("pooled before checking --out"))
    assert why in _refused(capsys, [runs / "s0", "--out", target])


def _exp5_dir(tmp_path: Path, config: str) -> Path:
    d = tmp_path / "exp5run"
    (d / ".hydra").mkdir(parents=True)
    (d / ".hydra" / "config.yaml").write_text(config)
    (d / "individuals.csv").write_text("hypothesis,level\n")
    (d / "summary.json").write_text("{}")
    return d


YAML_CASES = {
    "malformed": ("experiment: {name: exp5\nseed: [1,\n", "not a configuration this package wrote"),
    "python tag": ("experiment: !!python/object/apply:os.system ['touch {marker}']\nseed: 0\n",
                   "not a configuration this package wrote"),
    "python name tag": ("experiment:\n  name: !!python/name:os.system\nseed: 0\n", "not a configuration this package wrote"),
    "unknown resolver": ("experiment:\n  name: exp5\n  x: ${nosuch:1}\nseed: 0\n", "cannot be resolved"),
    "broken interpolation": ("experiment:\n  name: exp5\n  x: ${nowhere.key}\nseed: 0\n", "cannot be resolved"),
    "a list": ("- 1\n- 2\n", "cannot be read"),
    "binary": ("\udcff", "cannot be read"),
    "experiment not a mapping": ("experiment: 3\nseed: 0\n", "'experiment' is not a mapping"),
    "seed not a number": ("experiment:\n  name: exp5\nseed: abc\n", "seed 'abc' is not an integer"),
}


@pytest.mark.parametrize("case", list(YAML_CASES))
def test_a_saved_configuration_that_cannot_be_read_is_one_line_and_runs_nothing(tmp_path, case):
    text, why = YAML_CASES[case]
    marker = tmp_path / "ran"
    text = text.replace("{marker}", str(marker))
    if case == "binary":
        d = _exp5_dir(tmp_path, "")
        (d / ".hydra" / "config.yaml").write_bytes(b"\xff\xfe\x00bad")
    else:
        d = _exp5_dir(tmp_path, text)
    with pytest.raises(pool.UserInputError) as ex:
        exp5_pool.read_config(d)
    msg = str(ex.value)
    assert "\n" not in msg and str(d / ".hydra" / "config.yaml") in msg, msg
    assert why in msg or (case == "a list" and "not a mapping" in msg), msg
    assert not marker.exists()
