"""``python -m neuroimagery.robot.babble --out DIR``: a folder that cannot take the table is refused
before the first rollout, the table is written atomically, and a failed write keeps the computed
table in a file named in the ``error:`` line."""
import errno
import json
from pathlib import Path

import pytest

from neuroimagery.core import files
from neuroimagery.robot import babble
from neuroimagery.robot.events import EVENTS


def _table(rollouts: int = 4) -> dict:
    """A table of the shape ``babble.measure`` returns (measuring takes the simulator)."""
    n = len(EVENTS)
    table = {f"posture-{k}": {"events": [0] * n, "rates": [0.0] * n, "rates_ci95": [[0.0, 0.5]] * n,
                              "rates_per_seed": [[0.0] * n], "rollouts": rollouts} for k in range(1, 5)}
    rates = {k: v["rates"] for k, v in table.items()}
    return {**table, "possible_rate": babble.POSSIBLE_RATE, "seeds": 1,
            "agreement": {str(t): babble.agreement(rates, babble.THESIS_EVENTS, t) for t in babble.CURVE_THRESHOLDS}}


@pytest.fixture
def measured(monkeypatch):
    calls = []

    def fake(n, seeds, table_contact="lift", out=None, jobs=1):
        assert table_contact == "lift" and jobs == 1  # the default table rule, one process
        calls.append((n, seeds))
        return _table(n * seeds)

    monkeypatch.setattr(babble, "measure", fake)
    return calls


def _main(capsys, *argv) -> tuple[int, list[str]]:
    code = babble.main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, [ln for ln in err.splitlines() if ln.strip()]


@pytest.mark.parametrize("how,why", [
    ("an existing file", "is a file, not a folder"),
    ("a folder under a file", "cannot write into"),
    ("an output name that is a folder", "table_7_1.json is a folder"),
])
def test_an_out_that_cannot_take_the_table_is_refused_before_the_first_rollout(tmp_path, capsys, measured, how, why):
    f = tmp_path / "afile"
    f.write_text("x")
    out = {"an existing file": f, "a folder under a file": f / "sub", "an output name that is a folder": tmp_path / "o"}[how]
    if how == "an output name that is a folder":
        (out / "table_7_1.json").mkdir(parents=True)
    code, lines = _main(capsys, "--rollouts", 2, "--seeds", 1, "--out", out)
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: --out: ") and why in lines[0], lines
    assert measured == []  # no rollout


def test_an_unwritable_folder_is_refused_before_the_first_rollout(tmp_path, capsys, measured, monkeypatch):
    real = Path.write_text

    def read_only(self, *a, **k):  # as a read-only folder answers (root ignores the mode bits)
        if self.parent == tmp_path / "ro":
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self, *a, **k)

    (tmp_path / "ro").mkdir()
    monkeypatch.setattr(Path, "write_text", read_only)
    code, lines = _main(capsys, "--rollouts", 2, "--seeds", 1, "--out", tmp_path / "ro")
    assert code == 2 and lines == [f"error: --out: cannot write into {tmp_path / 'ro'} (Permission denied)"]
    assert measured == []


def test_the_table_is_written_and_stale_temporaries_removed(tmp_path, capsys, measured):
    out = tmp_path / "o"
    out.mkdir()
    (out / "table_7_1.json.999999.tmp").write_text("{")
    code, lines = _main(capsys, "--rollouts", 2, "--seeds", 1, "--out", out)
    assert code == 0 and lines == []
    assert json.loads((out / "table_7_1.json").read_text())["posture-1"]["rollouts"] == 2
    assert (out / "table_7_1.md").read_text().startswith("### Measured")
    assert not files.stale_temporaries(out)


def test_a_failed_write_keeps_the_computed_table_in_a_named_file(tmp_path, capsys, measured, monkeypatch):
    real = files.write_atomic

    def full(path, write):
        if Path(path).name == "table_7_1.md":
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, write)

    monkeypatch.setattr(files, "write_atomic", full)
    out = tmp_path / "o"
    code, lines = _main(capsys, "--rollouts", 3, "--seeds", 1, "--out", out)
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"error: cannot write {out / 'table_7_1.md'}: No space left on device; the computed "
                               "table is kept in "), lines
    spare = Path(lines[0].rsplit(" kept in ", 1)[1])
    assert json.loads(spare.read_text()) == json.loads(json.dumps(_table(3)))
    spare.unlink()


def test_an_interrupt_is_one_line_and_keeps_the_finished_pieces(tmp_path, capsys, monkeypatch):
    def stop_at_posture_2(world, posture, n, seed, cfg):
        if posture == 2:
            raise KeyboardInterrupt
        return [0] * len(EVENTS)

    monkeypatch.setattr(babble, "babble_counts", stop_at_posture_2)
    code, lines = _main(capsys, "--rollouts", 3, "--seeds", 2, "--out", tmp_path)
    assert code == 130 and lines == [f"interrupted: the finished postures x seeds are kept in {tmp_path / 'counts'}; "
                                     "the same command resumes"], lines
    assert sorted(p.name for p in (tmp_path / "counts").glob("*.json")) == ["posture1_seed0.json", "posture1_seed1.json"]
