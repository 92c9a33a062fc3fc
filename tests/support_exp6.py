"""One Experiment 6 participant trained as the protocol trains it (full sizes, one participant),
shared by the stage-contract tests of tests/contracts/test_exp6_*.py, and its own search and
transform on the pairs the contracts 6.2c, 6.3b and 6.4 read (computed once)."""
import os
from functools import lru_cache

from conftest import make_cfg

from neuroimagery.config import validate


SEED = int(os.environ.get("NEUROIMAGERY_CONTRACT_SEED", "0"))  # as tests/contracts/conftest.py


def cfg_for(*overrides):
    cfg = validate(make_cfg("experiment=exp6", "logger=none", "participants=1", f"seed={SEED}", *overrides))
    cfg.preset = "full"
    return cfg


@lru_cache(maxsize=1)
def trained():
    """(config, model, scene) of one participant at seed 0 (``NEUROIMAGERY_CONTRACT_SEED``: another)."""
    from neuroimagery.experiments.exp6 import protocol as exp6

    cfg = cfg_for()
    scene = exp6.make_scene(cfg.experiment)
    model = exp6.train_model(cfg, [0], scene)
    return cfg, model, scene


@lru_cache(maxsize=1)
def aligned(count: int = 4):
    """:func:`exp6_stages.alignment` of the trained participant: the training objects' pairs and
    ``count`` held-out chains' pairs."""
    from neuroimagery.experiments.exp6 import stages as exp6_stages

    cfg, model, scene = trained()
    return exp6_stages.alignment(model, cfg, scene, count)


def assert_every_set_and_kind(out: dict, floor: float) -> None:
    """A stage measure ``out[set][kind]`` at or above ``floor`` for the training objects and the
    held-out chains, in the picture plane and in depth."""
    print(out)
    for label in ("train", "held_out"):
        for kind in ("picture", "depth"):
            assert out[label][kind] >= floor, out
