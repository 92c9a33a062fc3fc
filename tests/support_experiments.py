"""Replacing parts of an experiment's protocol in a test."""
import dataclasses
import importlib


def patch_experiment(monkeypatch, name: str, **fields) -> None:
    """Replace fields of experiment ``name``'s protocol (``EXPERIMENT``) for one test."""
    package = importlib.import_module(f"neuroimagery.experiments.{name}")
    monkeypatch.setattr(package, "EXPERIMENT", dataclasses.replace(package.EXPERIMENT, **fields))
