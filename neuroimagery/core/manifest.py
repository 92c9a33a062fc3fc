"""Manifests: what a run and each of its checkpoints were made with.

A manifest names the experiment, the package version, the seed, the participants and every
setting that can change a result (``settings``), with the subset that shapes training
(``training``). ``manifest.json`` in a run directory holds the run's; every checkpoint file
carries its own, with a hash of the tensors it stores. Loading a checkpoint compares its
``training`` settings with those of the run that loads it and names each key that differs; a
run directory whose manifest differs from a new run's is refused unless ``overwrite=true``.

Each experiment (:class:`neuroimagery.core.experiment.Experiment`) may declare

- ``test_keys``: experiment keys read only while testing (a trained model does not depend on
  them, so a checkpoint can be tested with other values);
- ``runtime_keys``: experiment keys that change how fast a run goes, never a result.
"""
from __future__ import annotations

import dataclasses
import hashlib
from typing import Any, Mapping

FORMAT = 1
# top-level keys that change neither a trained model nor a result
NEUTRAL = ("checkpoint", "progress", "threads", "overwrite", "allow_large", "logger")
# top-level keys that only the tests read: the stimuli a trained model is tested on
TEST_ONLY = ("stimuli",)


def flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Dotted keys of a (nested) dataclass or mapping, with JSON-ready leaves."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        items = ((f.name, getattr(obj, f.name)) for f in dataclasses.fields(obj))
    elif isinstance(obj, Mapping):
        items = obj.items()
    else:
        return {prefix.rstrip("."): _plain(obj)}
    out: dict[str, Any] = {}
    for k, v in items:
        out.update(flatten(v, f"{prefix}{k}."))
    return out


def _plain(v: Any) -> Any:
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def build(conf, module) -> dict:
    """The manifest of a run of ``conf`` (a validated :class:`~neuroimagery.config.Config`)."""
    runtime = {f"experiment.{k}" for k in module.runtime_keys}
    test = {f"experiment.{k}" for k in module.test_keys}
    settings = {k: v for k, v in flatten(conf).items()
                if k.split(".")[0] not in NEUTRAL and k not in runtime}
    training = {k: v for k, v in settings.items() if k not in test and k.split(".")[0] not in TEST_ONLY}
    return {"format": FORMAT, "package": current_version(), "experiment": conf.experiment.name,
            "seed": conf.seed, "participants": conf.participants, "settings": settings, "training": training}


def differences(ours: Mapping[str, Any], theirs: Mapping[str, Any]) -> list[str]:
    """``key: theirs -> ours`` for every key whose value differs (or is missing on one side)."""
    out = []
    for k in sorted(set(ours) | set(theirs)):
        a, b = ours.get(k, "<absent>"), theirs.get(k, "<absent>")
        if a != b:
            out.append(f"{k} {b!r} (stored) vs {a!r} (this run)")
    return out


def tensor_hash(state: Any) -> str:
    """SHA-256 of every tensor in a (nested) checkpoint state, in key order, with its dtype and shape."""
    import torch  # here: the checks before any work read this module without torch

    h = hashlib.sha256()

    def walk(x: Any, path: str) -> None:
        if isinstance(x, torch.Tensor):
            t = x.detach().to("cpu").contiguous()
            h.update(f"{path}:{t.dtype}:{tuple(t.shape)};".encode())
            h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
        elif isinstance(x, Mapping):
            for k in sorted(x, key=str):
                walk(x[k], f"{path}/{k}")
        elif isinstance(x, (list, tuple)):
            for i, v in enumerate(x):
                walk(v, f"{path}[{i}]")

    walk(state, "")
    return h.hexdigest()


# ------------------------------------------------------------------------------ a run's state
# manifest.json of a run directory records, beside the manifest above, ``state``: ``running``
# from the moment work starts, then ``complete`` (every output written; ``files`` holds their
# SHA-256) or ``interrupted`` (stopped: Ctrl-C, SIGTERM, an error; ``stopped`` says how); and
# ``trained``: whether training finished and its checkpoints are whole. A run killed outright
# (SIGKILL, power) stays ``running`` with a lock whose process is gone (neuroimagery/core/lock.py).
STATES = ("running", "complete", "interrupted")
OUTPUTS = ("train.json", "trials.csv", "individuals.csv", "summary.json", "report.md")


def file_hash(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def output_hashes(root) -> dict[str, str]:
    """SHA-256 of the run's result files and checkpoints, by path relative to ``root``."""
    from pathlib import Path

    root = Path(root)
    paths = [root / n for n in OUTPUTS] + sorted((root / "checkpoints").glob("*.pt"))
    return {p.relative_to(root).as_posix(): file_hash(p) for p in paths if p.is_file()}


def _changed(root, files: Mapping[str, str], only: tuple[str, ...] | None = None) -> str | None:
    """The first file of ``files`` (relative paths -> hashes) missing or altered under ``root``."""
    from pathlib import Path

    for rel, digest in files.items():
        if only is not None and not rel.startswith(only):
            continue
        p = Path(root) / rel
        if not p.is_file():
            return f"{p}: missing (manifest.json lists it)"
        if file_hash(p) != digest:
            return f"{p}: changed since the run finished (its hash differs from the one in manifest.json)"
    return None


def verify_files(root, manifest: Mapping[str, Any], use: str, only: tuple[str, ...] | None = None) -> None:
    """Refuse a run whose files (those under the path prefixes ``only``, or all) are not those it
    finished with: each hash in ``manifest.json``'s ``files`` against the file itself."""
    from .errors import UserInputError

    files = manifest.get("files") if isinstance(manifest.get("files"), dict) else {}
    bad = _changed(root, files, only)
    if bad:
        raise UserInputError(f"{use}: {bad}")


def require_complete(root, manifest: Mapping[str, Any], use: str, trained_enough: bool = False,
                     script: str = "evaluate.py") -> None:
    """Refuse (``UserInputError``, ``use`` says for what) a run directory that is not complete.
    ``trained_enough``: a run whose training finished (``trained``) suffices. The files are checked
    by :func:`verify_files` (pooling) or by the hash of the tensors (checkpoints.py)."""
    from pathlib import Path

    from . import lock
    from .errors import UserInputError

    root = Path(root)
    state = manifest.get("state")
    if state is None:  # written by a 0.x release before runs recorded their state
        raise UserInputError(old_release(root, use, manifest, "written before runs recorded their state", script))
    if state == "complete" or (trained_enough and state in STATES and manifest.get("trained") is True):
        return
    if state == "running":
        holder = lock.read(root)
        alive = lock.holder_alive(holder) if holder else False
        if alive or alive is None and holder:
            why = f"still being written (host {holder.get('host')}, PID {holder.get('pid')})"
        else:
            why = "stopped before it finished (killed: its process is gone)"
    elif state == "interrupted":
        why = f"interrupted ({manifest.get('stopped') or 'stopped before it finished'})"
    else:
        why = f"in an unknown state {state!r}"
    raise UserInputError(f"{use}: {root} is not a complete run: {why}; its files may mix runs (run it again)")


# ------------------------------------------------------------------------------ releases
FIRST_MANIFEST = "0.1.0"  # the release whose runs had no manifest.json (the next one wrote them)


def current_version() -> str:
    """This package's release (``neuroimagery.__version__``)."""
    import neuroimagery

    return str(neuroimagery.__version__)


def major(version: Any) -> int | None:
    """The major number of a release string (``"1.0.0"`` -> 1); None when it is not one."""
    head = str(version).split(".")[0]
    return int(head) if head.isdigit() else None


def older_release(version: Any) -> bool:
    """Whether ``version`` (a stored manifest's ``package``) is of an earlier major release than
    this package: what it stored is not read (settings, checkpoints and task files change between
    major releases)."""
    stored, now = major(version), major(current_version())
    return stored is not None and now is not None and stored < now


def _hydra_file(root, name: str) -> Any:
    """The YAML file ``.hydra/<name>`` of a run directory, or None (absent, unreadable)."""
    from pathlib import Path

    import yaml

    try:
        return yaml.safe_load((Path(root) / ".hydra" / name).read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return None


def rerun_command(root, manifest: Mapping[str, Any] | None = None, script: str = "evaluate.py") -> str:
    """The command that runs a stored run again with this release: its experiment and seed (from
    its manifest, else its ``.hydra/overrides.yaml``) and the overrides it was run with."""
    loaded = _hydra_file(root, "overrides.yaml")
    overrides = [str(o) for o in loaded] if isinstance(loaded, list) else []
    composed = _hydra_file(root, "config.yaml")  # a run without a manifest: the configuration it ran
    composed = composed if isinstance(composed, dict) else {}
    given = dict(o.split("=", 1) for o in overrides if "=" in o)
    manifest = manifest or {}
    experiment = (manifest.get("experiment") or given.get("experiment")
                  or (composed.get("experiment") or {}).get("name") or "EXPERIMENT")
    seed = manifest.get("seed", given.get("seed", composed.get("seed")))
    skip = ("experiment=", "seed=", "hydra.", "checkpoint=", "overwrite=")
    args = [f"experiment={experiment}"] + ([f"seed={seed}"] if seed is not None else [])
    args += [o for o in overrides if not o.lstrip("+~").startswith(skip)]
    return " ".join(["python", script, *args])


def old_release(root, use: str, manifest: Mapping[str, Any] | None, why: str = "",
                script: str = "evaluate.py") -> str:
    """The one-line refusal of a run (or checkpoint) of an earlier release: its version, and the
    command that runs it again with this one."""
    version = (manifest or {}).get("package") or FIRST_MANIFEST
    return (f"{use}: {root} is a run of neuroimagery {version}{' (' + why + ')' if why else ''}, which "
            f"{current_version()} does not read; run it again: {rerun_command(root, manifest, script)}")


REQUIRED = ("experiment", "seed", "settings", "participants")  # what every manifest.json this package wrote holds


def usable_run(root, use: str, experiment: str | None = None, need: str = "complete",
               files: tuple[str, ...] | None = (), script: str = "evaluate.py") -> dict:
    """The one judgement of whether a stored run may be used (``use``: by ``pool``, ``checkpoint``,
    ``experiment.engine.reuse_libraries=...``, named in each refusal): its ``manifest.json`` is a
    manifest this package wrote (:data:`REQUIRED` keys, ``settings`` a mapping), of ``experiment``
    (if given), in the state ``need`` asks (``complete``; ``trained``: its training finished;
    ``any``), and the files it lists under ``files`` (path prefixes; ``()``: all, None: none) are
    those it finished with: the hash in ``manifest.json`` is checked against the file itself, so a
    file or a hash edited by hand is refused (a caller that first reads the files for a more precise
    message gives ``files=None`` and calls :func:`verify_files` after). A run of an earlier major
    release (or of 0.1.0, which wrote no manifest) is refused with the command that runs it again
    (``script``: the entry point that does). Returns the manifest; raises :class:`UserInputError`
    otherwise."""
    import json
    from pathlib import Path

    from .errors import UserInputError

    path = Path(root) / "manifest.json"
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        if (Path(root) / ".hydra").is_dir():  # a run directory of the release that wrote no manifest
            raise UserInputError(old_release(root, use, None, "no manifest.json", script)) from None
        raise UserInputError(f"{use}: {root}: no manifest.json (not a run directory)") from None
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise UserInputError(f"{use}: run manifest {path}: cannot be read ({getattr(err, 'strerror', None) or err})") from None
    if not isinstance(manifest, dict):
        raise UserInputError(f"{use}: {path}: not a JSON object")
    if experiment is not None and "experiment" in manifest and manifest["experiment"] != experiment:
        raise UserInputError(f"{use}: {root} is a run of {manifest['experiment']}, not of {experiment}")
    for key in REQUIRED:
        if key not in manifest:
            raise UserInputError(f"{use}: {path}: no {key!r} (not a manifest this package wrote, or edited by hand)")
    if not isinstance(manifest["settings"], dict):
        raise UserInputError(f"{use}: {path}: 'settings' is not a mapping (not a manifest this package wrote)")
    if older_release(manifest.get("package")):
        raise UserInputError(old_release(root, use, manifest, script=script))
    if need != "any":
        require_complete(root, manifest, use, trained_enough=need == "trained", script=script)
    if files is not None:
        verify_files(root, manifest, use, files or None)
    return manifest


def _smaller(key: str, limit):
    return lambda s: min(s[key], limit(s) if callable(limit) else limit)


# what preset=quick does to each experiment's settings: the key it changes and the value it uses
# (the experiments' own code: exp1/exp2 `_e`, exp3/exp4/exp6 `quick.*` counts, exp5 `quick.repetitions`)
QUICK_VALUES = {
    "exp1": {"experiment.som.iterations": _smaller("experiment.som.iterations", lambda s: s["experiment.quick.som_iterations"])},
    "exp2": {"experiment.som.iterations": _smaller("experiment.som.iterations", lambda s: s["experiment.quick.som_iterations"])},
    "exp3": {"experiment.fm.images": lambda s: s["experiment.quick.fm_images"]},
    "exp4": {"experiment.fm.images": lambda s: s["experiment.quick.fm_images"]},
    "exp5": {"experiment.repetitions": lambda s: s["experiment.quick.repetitions"]},
    "exp6": {"experiment.fm.images": lambda s: s["experiment.quick.fm_images"],
             "experiment.image.chains": lambda s: s["experiment.quick.chains"],
             "experiment.objects.test": lambda s: (min(s["experiment.objects.test"], s["experiment.quick.objects"])
                                                   if s.get("experiment.objects.test_cubes") is None
                                                   else s["experiment.objects.test"])},
}


def as_used(settings: dict, experiment: str) -> dict:
    """``settings`` (dotted keys) with the values a run used: under ``preset=quick`` each key the
    preset shrinks holds the quick value (TensorBoard's HParams view shows these)."""
    if settings.get("preset") != "quick":
        return dict(settings)
    out = dict(settings)
    for key, value in QUICK_VALUES.get(experiment, {}).items():
        try:
            out[key] = value(settings)
        except KeyError:  # a key the run does not have (an older schema): left as given
            pass
    return out
