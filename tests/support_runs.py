"""Reusing a finished run in a slow test: refuse one made with other settings."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from omegaconf import OmegaConf

# settings that decide a run's results: a reused run must have the ones the test composes
RUN_KEYS = ("experiment", "vision", "stimuli", "seed", "participants", "preset")


def reused_run(env: str, cfg) -> dict:
    """``summary.json`` of the run ``$env`` names, refused (pytest.fail) unless that directory is a
    finished run whose ``.hydra/config.yaml`` has ``cfg``'s values for ``RUN_KEYS``."""
    d = Path(os.environ[env])
    saved = d / ".hydra" / "config.yaml"
    if not (d / "summary.json").is_file() or not saved.is_file():
        pytest.fail(f"{env}={d}: no summary.json and .hydra/config.yaml there, not a finished evaluate.py run")
    try:
        run = OmegaConf.to_container(OmegaConf.load(saved), resolve=True)
    except Exception as err:  # unreadable or unresolvable: refuse rather than trust
        pytest.fail(f"{env}={d}: cannot read {saved}: {err}")
    want = OmegaConf.to_container(cfg, resolve=True)
    name, expected = (run.get("experiment") or {}).get("name"), want["experiment"]["name"]
    if name != expected:
        pytest.fail(f"{env}={d} is a run of experiment {name!r}, not {expected!r}")
    diff = []
    for k in RUN_KEYS:
        a, b = run.get(k), want.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            diff += [f"{k}.{s}: run {a.get(s)!r}, expected {b.get(s)!r}" for s in sorted(a.keys() | b.keys())
                     if a.get(s) != b.get(s)]
        elif a != b:
            diff.append(f"{k}: run {a!r}, expected {b!r}")
    if diff:
        pytest.fail(f"{env}={d} was not made with the settings this test expects:\n  " + "\n  ".join(diff))
    return json.loads((d / "summary.json").read_text())


def rehash(run_dir) -> None:
    """Record in ``run_dir/manifest.json`` the hashes of its files as they are now (as if the run had
    written them: a careful forger, or a file another version wrote)."""
    from neuroimagery.core import manifest as mf

    path = Path(run_dir) / "manifest.json"
    m = json.loads(path.read_text())
    m["files"] = {rel: mf.file_hash(Path(run_dir) / rel) for rel in m.get("files", {}) if (Path(run_dir) / rel).is_file()}
    path.write_text(json.dumps(m))
