"""``checkpoint=DIR``: every checkpoint that cannot be used is one ``error:`` line naming it, before
any work and without claiming the run directory; nothing in a file is run; no message repeats
torch's advice to load a file with ``weights_only=False``."""
import json
import shutil
from pathlib import Path

import pytest
import torch
from conftest import make_cfg

from neuroimagery.app import cli
from neuroimagery.core import manifest as mf
from support_runs import rehash
from neuroimagery.app.run import evaluate, train


def _demo(*over):
    return make_cfg("experiment=demo", "participants=2", "progress=false", "logger=none", *over)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    d = tmp_path_factory.mktemp("ck") / "tr"
    train(_demo(), out_dir=d)
    return d


def _copy(trained, tmp_path) -> Path:
    d = tmp_path / "tr"
    shutil.copytree(trained, d)
    return d


def _resave(d: Path, change) -> Path:
    """Alter the checkpoint's state with ``change`` and store it again with its hashes recomputed,
    inside the file and in the run's manifest.json (as a careful forger, or another version, would)."""
    ck = d / "checkpoints" / "model.pt"
    state = torch.load(ck, weights_only=True)
    man = state.pop("manifest")
    change(state, man)
    torch.save({**state, "manifest": {**man, "tensor_hash": mf.tensor_hash(state)}}, ck)
    rehash(d)
    return ck


def _refused(capsys, d: Path, tmp_path: Path) -> str:
    out = tmp_path / "ev"
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(evaluate)(_demo(f"checkpoint={d}"), out_dir=out)
    err = capsys.readouterr().err
    assert ex.value.code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    assert "weights_only" not in err
    assert not out.exists()  # refused before the run directory was made
    return lines[0]


def _drop_key(state, man):
    state["state_dict"].pop(next(iter(state["state_dict"])))


def _reshape(state, man):
    k = next(k for k, v in state["state_dict"].items() if v.dim() > 0)
    state["state_dict"][k] = torch.zeros(3, 3, 3)


CASES = {
    "a state_dict key missing": (_drop_key, "does not fit this experiment's model (Error(s) in loading state_dict"),
    "a tensor of another shape": (_reshape, "does not fit this experiment's model"),
    "no participants": (lambda s, m: s.pop("participants"), "does not fit this experiment's model (no entry 'participants')"),
    "manifest without training": (lambda s, m: m.pop("training"), "its manifest has no 'training' settings"),
    "manifest without experiment": (lambda s, m: m.pop("experiment"), "was trained for None, not demo"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_checkpoint_that_does_not_fit_is_one_line(trained, tmp_path, capsys, case):
    change, why = CASES[case]
    d = _copy(trained, tmp_path)
    _resave(d, change)
    assert why in _refused(capsys, d, tmp_path)


class _Payload:
    def __reduce__(self):
        import os
        return (os.system, (f"touch {_Payload.marker}",))


def test_a_crafted_pickle_is_refused_without_running_it_or_advising_weights_only_false(trained, tmp_path, capsys):
    d = _copy(trained, tmp_path)
    _Payload.marker = tmp_path / "ran"
    torch.save({"state_dict": _Payload()}, d / "checkpoints" / "model.pt")
    line = _refused(capsys, d, tmp_path)
    assert "not a checkpoint this package wrote, or corrupt; nothing in it was run" in line
    assert "global" in line.lower() and "system" in line, line  # what torch refused to load
    assert not _Payload.marker.exists()


@pytest.mark.parametrize("damage,why", [
    (lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]), "or corrupt"),
    (lambda p: p.write_text("not a checkpoint"), "or corrupt"),
    (lambda p: p.write_bytes(b""), "or corrupt"),
    (lambda p: torch.save([1, 2, 3], p), "has no manifest"),
])
def test_a_damaged_checkpoint_file_is_one_line(trained, tmp_path, capsys, damage, why):
    d = _copy(trained, tmp_path)
    damage(d / "checkpoints" / "model.pt")
    assert why in _refused(capsys, d, tmp_path)


@pytest.mark.parametrize("edit,why", [
    (lambda m: "{cut", "run manifest"),
    (lambda m: json.dumps({**m, "state": "running", "trained": False}), "not a complete run: stopped before it finished"),
    (lambda m: json.dumps({**m, "state": "interrupted", "trained": False, "stopped": "x"}), "not a complete run: interrupted"),
    (lambda m: json.dumps({**m, "state": "sideways"}), "unknown state 'sideways'"),
])
def test_a_training_run_that_did_not_finish_is_refused(trained, tmp_path, capsys, edit, why):
    d = _copy(trained, tmp_path)
    m = json.loads((d / "manifest.json").read_text())
    (d / "manifest.json").write_text(edit(m))
    assert why in _refused(capsys, d, tmp_path)


def test_a_training_run_written_before_the_state_is_refused_with_the_command_that_reruns_it(trained, tmp_path, capsys):
    d = _copy(trained, tmp_path)
    m = json.loads((d / "manifest.json").read_text())
    for k in ("state", "trained", "files"):
        m.pop(k)
    (d / "manifest.json").write_text(json.dumps(m))
    line = _refused(capsys, d, tmp_path)
    assert f"is a run of neuroimagery {m['package']} (written before runs recorded their state)" in line
    assert line.endswith("run it again: python train.py experiment=demo seed=0"), line


def test_a_run_of_a_0x_release_is_refused_in_one_line_naming_its_version_and_command(trained, tmp_path, capsys,
                                                                                    monkeypatch):
    """A fake 0.x manifest read by a 1.x release: its version and the command that runs it again,
    with the overrides its run recorded."""
    import neuroimagery

    d = _copy(trained, tmp_path)
    m = json.loads((d / "manifest.json").read_text())
    (d / "manifest.json").write_text(json.dumps({**m, "package": "0.2.0"}))
    (d / ".hydra").mkdir(exist_ok=True)
    (d / ".hydra" / "overrides.yaml").write_text("- experiment=demo\n- participants=2\n- seed=0\n- hydra.verbose=true\n")
    monkeypatch.setattr(neuroimagery, "__version__", "1.0.0")
    line = _refused(capsys, d, tmp_path)
    assert line == (f"error: checkpoint: {d} is a run of neuroimagery 0.2.0, which 1.0.0 does not read; run it "
                    "again: python train.py experiment=demo seed=0 participants=2")
    # a checkpoint file of a 0.x release in a run directory of this one
    from neuroimagery.core.checkpoints import verify_checkpoint
    from neuroimagery.core.errors import UserInputError

    ck = d / "checkpoints" / "model.pt"
    state = torch.load(ck, weights_only=True)
    torch.save({**state, "manifest": {**state["manifest"], "package": "0.1.5"}}, ck)
    with pytest.raises(UserInputError, match=r"is a run of neuroimagery 0\.1\.5, which 1\.0\.0 does not read"):
        verify_checkpoint(d, "model", {**m, "package": "1.0.0"})
    # a run directory without manifest.json: written by 0.1.0
    (d / "manifest.json").unlink()
    line = _refused(capsys, d, tmp_path)
    assert "is a run of neuroimagery 0.1.0 (no manifest.json)" in line and "python train.py experiment=demo" in line
