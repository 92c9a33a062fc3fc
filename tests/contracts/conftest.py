"""Trained Experiment 3 and 4 models shared by the contract tests: seed 0, two participants, the
protocol's own training (three-dot forward models on the full protocol's 4000 images, posture maps
on the training set). ``NEUROIMAGERY_CONTRACT_SEED=S`` measures them on seed S instead (the
contracts over seeds 0-4: ``for S in 0 1 2 3 4; do NEUROIMAGERY_CONTRACT_SEED=$S pytest
tests/contracts/test_exp3_* tests/contracts/test_exp4_*; done``)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from neuroimagery.config import validate
from neuroimagery.experiments.exp3 import protocol as exp3
from neuroimagery.experiments.exp4 import protocol as exp4
from neuroimagery.experiments.chapter6 import protocol as pc

PARTICIPANTS = [0, 1]
SEED = int(os.environ.get("NEUROIMAGERY_CONTRACT_SEED", "0"))
CONF = str(Path(__file__).resolve().parents[2] / "conf")


def make_cfg(*overrides: str):
    with initialize_config_dir(config_dir=CONF, version_base="1.3"):
        return compose("config", overrides=list(overrides))


def ch6_cfg(name: str, *overrides: str):
    # the forward models see the full protocol's three-dot images; quick only shrinks the test sets
    cfg = validate(make_cfg(f"experiment={name}", "participants=2", "logger=none", f"seed={SEED}",
                            "experiment.quick.fm_images=4000", *overrides))
    cfg.preset = "quick"
    return cfg


class Trained:
    """A trained model with its config, eye and the edge-map banks of its sets."""

    def __init__(self, module, cfg):
        self.cfg, self.e = cfg, cfg.experiment
        self.eye = pc.make_eye(cfg)
        self.model = module.train_model(cfg, PARTICIPANTS, self.eye)
        self._banks = {}

    def bank(self, name: str) -> pc.StimulusBank:
        """The training set as the model was trained on it (its training looks); any other set as drawn."""
        if name not in self._banks:
            self._banks[name] = (pc.training_bank(self.cfg, self.eye) if name == self.e.train_set else
                                 pc.StimulusBank.build(self.eye, pc.stimulus_set(self.cfg, name, False), self.e.map_size))
        return self._banks[name]

    def looks(self, name: str):
        """``(L, N, n)`` looks at the items of ``name`` as the first test builds them (rule R4)."""
        key = ("looks", name)
        if key not in self._banks:
            self._banks[key] = pc.test_bank(self.cfg, self.eye, pc.stimulus_set(self.cfg, name, False), 0).looks
        return self._banks[key]


@pytest.fixture(scope="session")
def trained3():
    return Trained(exp3, ch6_cfg("exp3"))


@pytest.fixture(scope="session")
def trained4():
    return Trained(exp4, ch6_cfg("exp4"))
