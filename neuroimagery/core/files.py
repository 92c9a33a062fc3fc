"""Writing a result file atomically: into a temporary name of the writing process, then renamed
over the target, so a reader never sees half a file and two writers (a run and its rerun, two
workers) never share a temporary name. A process killed mid-write leaves only its temporary file
(``<name>.<pid>.tmp``), which the next run into that directory removes
(:func:`remove_stale_temporaries`). Used by the run directory (``neuroimagery.app.run.RunDir``), the
figures, the reports, pooling, babbling and Experiment 5's task files; :func:`kept_json` keeps the
pieces of the long world measurements (babbling, skill libraries) for a rerun to reuse."""
from __future__ import annotations

import io
import os
import re
from collections.abc import Callable
from pathlib import Path

_TMP = re.compile(r"\.\d+\.tmp$")


def tmp_path(path: str | Path) -> Path:
    """This process's temporary name for ``path``."""
    path = Path(path)
    return path.with_name(f"{path.name}.{os.getpid()}.tmp")


def unlink_quietly(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


def write_atomic(path: str | Path, write: Callable[[Path], object]) -> Path:
    """``write(tmp)`` into this process's temporary name, then rename it to ``path``. The temporary
    file is removed if anything goes wrong (an interrupt included); an ``OSError`` is raised
    naming ``path`` (not the temporary name), any other error as it came."""
    path = Path(path)
    tmp = tmp_path(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as err:
        unlink_quietly(tmp)
        raise OSError(err.errno, err.strerror or str(err), str(path)) from None
    except BaseException:
        unlink_quietly(tmp)
        raise
    return path


def write_text(path: str | Path, text: str) -> Path:
    """``text`` into ``path``, atomically."""
    return write_atomic(path, lambda p: Path(p).write_text(text))


def kept_json(path: str | Path, settings: dict, compute: Callable[[], object]) -> object:
    """A piece of a long measurement that a rerun reuses: the result kept in ``path`` when it was
    computed with the same ``settings`` (anything JSON can hold), else ``compute()``, kept there at
    once (atomically) with its settings. A damaged or foreign file is computed again."""
    import json

    path = Path(path)
    settings = json.loads(json.dumps(settings))  # as the kept file reads back (tuples as lists)
    if path.is_file():
        try:
            kept = json.loads(path.read_text())
        except (OSError, ValueError):
            kept = None
        if isinstance(kept, dict) and kept.get("settings") == settings and "result" in kept:
            return kept["result"]
    result = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(dict(settings=settings, result=result)))
    return result


def save_figure(fig, path: str | Path, **kwargs) -> Path:
    """``fig.savefig`` into ``path`` atomically (the format from the name's suffix, as the
    temporary name has none): a kill leaves the previous figure, never a 0-byte or cut one."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    return write_atomic(path, lambda p: fig.savefig(p, format=fmt, **kwargs))


def torch_save(obj, path: Path) -> None:
    """``torch.save`` into memory, then the bytes into ``path`` with an ordinary write, flushed to
    disk before the rename: a failed write (a full disk) is an ``OSError`` naming ``path`` (torch
    writing to a file itself reports it as a ``RuntimeError`` about stream positions)."""
    import torch  # here: modules the checks before any work read import this one

    buf = io.BytesIO()
    torch.save(obj, buf)
    with open(path, "wb") as f:
        f.write(buf.getbuffer())
        f.flush()
        os.fsync(f.fileno())


def stale_temporaries(root: str | Path) -> list[Path]:
    """Temporary files (``<name>.<pid>.tmp``) under ``root``: those a killed process left."""
    root = Path(root)
    if not root.is_dir():
        return []
    return sorted(p for p in root.rglob("*.tmp") if _TMP.search(p.name) and p.is_file() and not p.is_symlink())


def remove_stale_temporaries(root: str | Path) -> list[Path]:
    """Remove the temporary files a killed run left under ``root`` (call it while holding the
    directory's lock: no live writer then uses them); returns those removed."""
    gone = []
    for p in stale_temporaries(root):
        try:
            p.unlink()
            gone.append(p)
        except OSError:
            pass
    return gone


def writable_folder(out: str | Path, outputs: tuple[str, ...] = (), refuse_run_dir: bool = False) -> Path:
    """A tool's ``--out`` checked before its work: a folder (made if absent) this process can write
    into, not a run directory (with ``refuse_run_dir``), whose output names are not folders; stale
    temporaries of a killed earlier call are removed. Refusals are :class:`UserInputError`."""
    from .errors import UserInputError

    out = Path(out)
    if refuse_run_dir and (out / "manifest.json").exists():
        raise UserInputError(f"--out: {out} is a run directory (it has manifest.json): choose another")
    if out.exists() and not out.is_dir():
        raise UserInputError(f"--out: {out} is a file, not a folder: choose another")
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = tmp_path(out / ".write-test")
        probe.write_text("")
        probe.unlink()
    except OSError as err:
        raise UserInputError(f"--out: cannot write into {out} ({err.strerror or err})") from None
    for name in outputs:
        if (out / name).is_dir():
            raise UserInputError(f"--out: {out / name} is a folder; the table is written under that name")
    remove_stale_temporaries(out)
    return out
