"""Reading a trained run's checkpoints (``evaluate.py checkpoint=DIR``): nothing in a file is
executed (``torch.load(weights_only=True)``), the stored tensors must match the hash their
manifest carries, the run must be complete (or at least its training: ``manifest.json``'s
``trained``), and every way a file can fail to fit the model is one ``error:`` line naming it.
"""
from __future__ import annotations

import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import torch

from . import console, manifest as mf
from .errors import UserInputError

# torch's refusal of an unsafe pickle advises loading it unsafely; never repeat that advice
_UNSAFE_ADVICE = ("weights_only", "trust the source", "torch.serialization", "add_safe_globals", "safe_globals",
                  "In PyTorch", "Check the documentation", "https://")


def read_json(path: Path, what: str = "") -> dict:
    """A JSON object from ``path``; a missing, unreadable or corrupt file is a :class:`UserInputError`
    naming ``what`` and the path."""
    name = f"{what} {path}".strip()
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise UserInputError(f"{name}: cannot be read ({getattr(err, 'strerror', None) or err})") from None
    if not isinstance(data, dict):
        raise UserInputError(f"{name}: not a JSON object")
    return data


def _reason(err: BaseException) -> str:
    """The part of a loading error worth showing: torch's own description of what it refused,
    without its advice to load the file unsafely."""
    lines = [ln.strip() for ln in str(err).splitlines() if ln.strip()]
    picked = [ln for ln in lines if ln.startswith(("WeightsUnpickler error", "Unsupported global", "Unsupported operand"))]
    keep = [ln for ln in (picked or lines) if not any(a in ln for a in _UNSAFE_ADVICE)]
    text = "; ".join(keep) or type(err).__name__
    for a in _UNSAFE_ADVICE:  # a line that merged the advice into the reason
        cut = text.find(a)
        if cut > 0 and a in ("weights_only", "add_safe_globals", "safe_globals"):
            text = text[:cut].rstrip(" ;,.(`")
    return text[:200]


def safe_load(path: str | Path) -> Any:
    """``torch.load`` with ``weights_only=True``: tensors and plain containers only, so nothing in
    the file is executed. A file that is not such a checkpoint is a :class:`UserInputError`."""
    path = Path(path)
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, zipfile.BadZipFile, ValueError, TypeError,
            AttributeError, ImportError, IndexError, KeyError) as err:
        raise UserInputError(f"checkpoint {path}: not a checkpoint this package wrote, or corrupt; "
                             f"nothing in it was run ({_reason(err)})") from None
    except (FileNotFoundError, PermissionError, IsADirectoryError) as err:
        raise UserInputError(f"checkpoint {path}: cannot be read ({err.strerror or err})") from None
    except OSError as err:  # torch reading a cut or foreign file
        raise UserInputError(f"checkpoint {path}: not a checkpoint this package wrote, or corrupt; "
                             f"nothing in it was run ({err.strerror or _reason(err)})") from None


def checkpoint_file(checkpoint: str | Path, name: str, experiment: str) -> Path:
    path = Path(checkpoint) / "checkpoints" / f"{name}.pt"
    if not path.exists():
        raise UserInputError(f"checkpoint: no {path} (is {checkpoint} the directory of a training run of {experiment}?)")
    return path


def load_checkpoint(checkpoint: str | Path, name: str) -> dict:
    """Read ``checkpoints/<name>.pt`` of a training run's directory, with a clear error if absent."""
    path = checkpoint_file(checkpoint, name, "this experiment")
    state = safe_load(path)
    if not isinstance(state, dict):
        raise UserInputError(f"checkpoint {path}: holds a {type(state).__name__}, not a checkpoint of this package")
    state.pop("manifest", None)
    return state


def verify_checkpoint(checkpoint: str | Path, name: str, manifest: dict) -> None:
    """Check ``checkpoints/<name>.pt`` against this run's ``manifest``: the tensors are those it
    stored (hash), and it was trained with the same settings; every differing key is named."""
    path = checkpoint_file(checkpoint, name, manifest["experiment"])
    state = safe_load(path)
    stored = state.pop("manifest", None) if isinstance(state, dict) else None
    if not isinstance(stored, dict):  # 0.1.0 wrote checkpoints without one
        raise UserInputError(f"checkpoint {path}: has no manifest (written by neuroimagery {mf.FIRST_MANIFEST}, which "
                             f"{mf.current_version()} does not read, or not by this package); train it again: "
                             f"{mf.rerun_command(checkpoint, None, 'train.py')}")
    if mf.older_release(stored.get("package")):
        raise UserInputError(mf.old_release(path, "checkpoint", stored, script="train.py"))
    if stored.get("tensor_hash") != mf.tensor_hash(state):
        raise UserInputError(f"checkpoint {path}: its tensors do not match the hash it stores (altered or corrupt)")
    if stored.get("experiment") != manifest["experiment"]:
        raise UserInputError(f"checkpoint: {checkpoint} was trained for {stored.get('experiment')}, "
                             f"not {manifest['experiment']}")
    training = stored.get("training")
    if not isinstance(training, dict):
        raise UserInputError(f"checkpoint {path}: its manifest has no 'training' settings (not a checkpoint this "
                             "package wrote)")
    diff = mf.differences(manifest["training"], training)
    if diff:
        raise UserInputError(f"checkpoint {path} was trained with other settings: {'; '.join(diff)} "
                             "(set them as in training, or train again)")
    if stored.get("package") != manifest["package"]:
        console.note(f"checkpoint {path} was written by version {stored.get('package')} (this is "
                     f"{manifest['package']})")


def verify_run(checkpoint: str | Path, names, manifest: dict) -> None:
    """``checkpoint=DIR`` before any work: a directory holding a run whose training finished
    (``manifest.json``), each checkpoint verified (:func:`verify_checkpoint`)."""
    ck = Path(checkpoint)
    if not ck.is_dir():
        raise UserInputError(f"checkpoint: {ck} is not a directory")
    for name in names:  # a directory that holds none is named by the file it lacks
        checkpoint_file(ck, name, manifest["experiment"])
    stored = mf.usable_run(ck, "checkpoint", need="trained", files=None, script="train.py")
    for name in names:
        verify_checkpoint(ck, name, manifest)
    # the checkpoints as the run wrote them (the hashes in manifest.json)
    mf.verify_files(ck, stored, "checkpoint", only=("checkpoints/",))


# errors a model's loading raises on a checkpoint that passed the checks above but does not fit
_MISFIT = (KeyError, RuntimeError, TypeError, ValueError, IndexError, AttributeError)


def load_model(module, conf, checkpoint: str | Path):
    """``module.load(conf, checkpoint)`` (``module``: the experiment's protocol,
    :class:`neuroimagery.core.experiment.Experiment`); a checkpoint that does not fit the model (a missing or
    extra entry, a tensor of another shape) is one ``error:`` line naming the directory."""
    try:
        return module.load(conf, Path(checkpoint))
    except UserInputError:
        raise
    except _MISFIT as err:
        if isinstance(err, KeyError):
            why = f"no entry {err.args[0]!r}" if err.args else "an entry is missing"
        else:
            lines = [ln.strip() for ln in str(err).splitlines() if ln.strip()]
            why = "; ".join(lines)[:300] or type(err).__name__
        raise UserInputError(f"checkpoint {Path(checkpoint) / 'checkpoints'}: does not fit this experiment's model "
                             f"({why}); train it again with this version") from None
