"""Manifests: what a run and each of its checkpoints were made with.

A manifest names the experiment, the package version, the seed, the participants and every
setting that can change a result (``settings``), with the subset that shapes training
(``training``). ``manifest.json`` in a run directory holds the run's; every checkpoint file
carries its own, with a hash of the tensors it stores. Loading a checkpoint compares its
``training`` settings with those of the run that loads it and names each key that differs; a
run directory whose manifest differs from a new run's is refused unless ``overwrite=true``.

Each experiment module may declare

- ``TEST_KEYS``: experiment keys read only while testing (a trained model does not depend on
  them, so a checkpoint can be tested with other values);
- ``RUNTIME_KEYS``: experiment keys that change how fast a run goes, never a result.
"""
from __future__ import annotations

import dataclasses
import hashlib
from importlib import metadata
from typing import Any, Mapping

import torch

FORMAT = 1
# top-level keys that change neither a trained model nor a result
NEUTRAL = ("checkpoint", "progress", "threads", "overwrite", "allow_large", "logger")
# top-level keys that only the tests read: the stimuli a trained model is tested on
TEST_ONLY = ("stimuli",)


def package_version() -> str:
    try:
        return metadata.version("neuroimagery")
    except metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "unknown"


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
    runtime = {f"experiment.{k}" for k in getattr(module, "RUNTIME_KEYS", ())}
    test = {f"experiment.{k}" for k in getattr(module, "TEST_KEYS", ())}
    settings = {k: v for k, v in flatten(conf).items()
                if k.split(".")[0] not in NEUTRAL and k not in runtime}
    training = {k: v for k, v in settings.items() if k not in test and k.split(".")[0] not in TEST_ONLY}
    return {"format": FORMAT, "package": package_version(), "experiment": conf.experiment.name,
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
