"""Shared fixtures: compose the real Hydra config and shrink it."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir

from neuroimagery.config import register_configs

CONF = str(Path(__file__).resolve().parents[1] / "conf")
register_configs()
torch.set_num_threads(1)  # small tensors: one thread avoids OpenMP spin-waits on a busy machine


def make_cfg(*overrides: str):
    """Compose ``conf/config.yaml`` with ``overrides`` (what ``python train.py ...`` would see)."""
    with initialize_config_dir(config_dir=CONF, version_base="1.3"):
        return compose("config", overrides=list(overrides))


@pytest.fixture
def cfg_factory():
    return make_cfg
