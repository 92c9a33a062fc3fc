"""Every file a run writes appears whole or not at all: figures, checkpoints, report.md, tables and
summary.json go through a temporary name of the writing process; the temporary files of a killed
run are removed by the next run into that directory; a full disk (``ENOSPC`` injected into the
write path) is one ``error:`` line naming the file, the trained model kept."""
import errno
import json
import threading
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402
from conftest import make_cfg  # noqa: E402

from neuroimagery.app import cli

from neuroimagery.core import files  # noqa: E402
from neuroimagery.app import run as run_mod  # noqa: E402
from neuroimagery.analysis.report import Report  # noqa: E402
from neuroimagery.app.run import evaluate, train  # noqa: E402


def _demo(*over):
    return make_cfg("experiment=demo", "participants=2", "progress=false", *over)


def _one_error(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


def _refused(capsys, fn, *args, **kwargs) -> str:
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(fn)(*args, **kwargs)
    assert ex.value.code == 2
    return _one_error(capsys)


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    files.write_text(target, "old")

    def half_then_fail(p):
        Path(p).write_text("half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as ex:
        files.write_atomic(target, half_then_fail)
    assert ex.value.errno == errno.ENOSPC and ex.value.filename == str(target)  # named by its own name
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_a_figure_is_written_whole_in_the_format_of_its_name(tmp_path, monkeypatch):
    fig = plt.figure(figsize=(1, 1))
    path = files.save_figure(fig, tmp_path / "f.png")
    good = path.read_bytes()
    assert good[:8] == b"\x89PNG\r\n\x1a\n"
    real = matplotlib.figure.Figure.savefig

    def cut(self, fname, **kw):  # a figure cut short by a failing disk
        real(self, fname, **kw)
        Path(fname).write_bytes(Path(fname).read_bytes()[:10])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", cut)
    with pytest.raises(OSError):
        files.save_figure(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").read_bytes() == good  # the previous figure, not a cut one
    assert [p.name for p in tmp_path.iterdir()] == ["f.png"]
    plt.close(fig)


def test_report_write_is_atomic(tmp_path, monkeypatch):
    r = Report("t").p("x")
    r.write(tmp_path / "report.md")
    before = (tmp_path / "report.md").read_text()
    monkeypatch.setattr(Path, "write_text", lambda self, t, *a, **k: (_ for _ in ()).throw(
        OSError(errno.ENOSPC, "No space left on device")))
    with pytest.raises(OSError):
        Report("u").p("y").write(tmp_path / "report.md")
    monkeypatch.undo()
    assert (tmp_path / "report.md").read_text() == before
    assert not files.stale_temporaries(tmp_path)


def test_the_next_run_removes_the_temporaries_of_a_killed_run(tmp_path, capsys):
    d = tmp_path / "run"
    evaluate(_demo("logger=none"), out_dir=d)
    junk = [d / "checkpoints" / "model.pt.999999.tmp", d / "figures" / "rt_by_disparity.png.999998.tmp",
            d / "summary.json.999997.tmp"]
    for p in junk:
        p.write_bytes(b"\0" * 100)
    keep = d / "notes.tmp"  # not a name this package writes: left alone
    keep.write_text("mine")
    capsys.readouterr()
    evaluate(_demo("logger=none"), out_dir=d)
    err = capsys.readouterr().err
    assert "removed 3 temporary file(s) that a killed run left" in err
    assert not any(p.exists() for p in junk) and keep.exists()
    assert not files.stale_temporaries(d)
    assert all(p.stat().st_size > 0 for p in d.rglob("*") if p.is_file() and p != keep)


def _enospc_on(monkeypatch, match: str):
    """Make the write of every file whose name ends with ``match`` fail as on a full disk, after
    part of it was written (the write path of run directories: ``files.write_atomic``)."""
    real = files.write_atomic

    def failing(path, write):
        if str(path).endswith(match):
            def half(tmp):
                Path(tmp).write_bytes(b"partial")
                raise OSError(errno.ENOSPC, "No space left on device")
            return real(path, half)
        return real(path, write)

    monkeypatch.setattr(run_mod, "write_atomic", failing)


def test_a_full_disk_at_the_checkpoint_keeps_the_model_in_a_named_folder(tmp_path, monkeypatch, capsys):
    _enospc_on(monkeypatch, "model.pt")
    line = _refused(capsys, train, _demo("logger=none"), out_dir=tmp_path / "run")
    ck = tmp_path / "run" / "checkpoints" / "model.pt"
    assert line.startswith(f"error: cannot write {ck}: No space left on device; kept in "), line
    spare = Path(line.split("; kept in ")[1])
    state = torch.load(spare, weights_only=True)  # the trained model, whole
    assert "state_dict" in state and state["manifest"]["experiment"] == "demo"
    assert not ck.exists() and not files.stale_temporaries(tmp_path / "run")
    m = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert m["state"] == "interrupted" and "No space left" in m["stopped"]
    assert not (tmp_path / "run" / "run.lock").exists()


def test_a_full_disk_while_testing_names_the_file_and_where_the_model_is(tmp_path, monkeypatch, capsys):
    _enospc_on(monkeypatch, "summary.json")
    d = tmp_path / "run"
    line = _refused(capsys, evaluate, _demo("logger=none"), out_dir=d)
    assert line.startswith(f"error: cannot write {d / 'summary.json'}: No space left on device"), line
    assert f"the trained model is whole in {d / 'checkpoints'}" in line
    assert (d / "checkpoints" / "model.pt").stat().st_size > 0 and (d / "trials.csv").stat().st_size > 0
    assert not (d / "summary.json").exists() and not files.stale_temporaries(d)


def test_a_full_disk_under_tensorboard_is_one_line_naming_the_event_file(tmp_path, monkeypatch, capfd):
    from tensorboard.summary.writer import record_writer

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(record_writer.RecordWriter, "write", full)
    seen = []
    monkeypatch.setattr(threading, "excepthook", lambda args: seen.append(args))  # what would be printed
    d = tmp_path / "run"
    with pytest.raises(SystemExit) as ex:
        cli.friendly_errors(evaluate)(_demo("logger=tensorboard"), out_dir=d)
    assert ex.value.code == 2
    err = capfd.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "No space left on device" in lines[0] and "Traceback" not in err, err
    assert lines[0].startswith(f"error: {d / 'tb'}")  # the event file, or its folder where none was made yet
    assert not any(isinstance(a.exc_value, OSError) for a in seen)  # the writer thread printed nothing
    assert json.loads((d / "manifest.json").read_text())["state"] == "interrupted"


def test_a_full_disk_inside_torch_save_is_an_oserror_naming_the_checkpoint(tmp_path, monkeypatch, capsys):
    """ENOSPC from the file's own write (where torch writing a file itself reported "unexpected pos")."""
    real_open = open
    run_dir = tmp_path / "run"

    class Full:
        def __init__(self, f):
            self.f = f

        def write(self, data):  # as a full disk answers: part written, the rest refused at the flush
            data = bytes(data)
            self.f.write(data[: len(data) // 2])
            return len(data) // 2

        def flush(self):
            raise OSError(errno.ENOSPC, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.f, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    def fake_open(path, mode="r", *a, **k):
        f = real_open(path, mode, *a, **k)
        return Full(f) if "w" in mode and str(path).startswith(str(run_dir)) else f

    monkeypatch.setattr(files, "open", fake_open, raising=False)
    line = _refused(capsys, train, _demo("logger=none"), out_dir=run_dir)
    assert line.startswith(f"error: cannot write {run_dir / 'checkpoints' / 'model.pt'}: No space left on device; "
                           "kept in "), line
    spare = Path(line.split("; kept in ")[1])
    assert torch.load(spare, weights_only=True)["manifest"]["experiment"] == "demo"
    assert not files.stale_temporaries(run_dir)
