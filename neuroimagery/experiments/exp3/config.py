"""Experiment 3's schema (``experiment.*``) and what the checks before any work read of it
(:mod:`neuroimagery.validation`, :mod:`neuroimagery.core.manifest`; the memory estimate and the
stimulus sets: :mod:`..chapter6.checks`): nothing heavy is imported here."""
from __future__ import annotations

from dataclasses import dataclass, field

from ...models.rotation_generalising_params import GeneralisingParams
from ..chapter6.config import PerceptParams, QuickParams


@dataclass
class Exp3Config(GeneralisingParams):
    """The model's parameters (:class:`GeneralisingParams`) and the run's: the stimulus sets, what
    ``preset=quick`` shrinks."""

    name: str = "exp3"
    train_set: str = "exp3-a"  # set whose images train C2/C3 (thesis: set a)
    recog_set: str = "exp3-a"  # Recog
    gen1_set: str = "exp3-b"  # Gen-I
    gen2_set: str = "exp3-c"  # Gen-II
    quick: QuickParams = field(default_factory=QuickParams)  # what preset=quick shrinks
    percept: PerceptParams = field(default_factory=PerceptParams)  # how the percept varies (rule R4)


CONFIG = Exp3Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ("vision", "stimuli")
CHECKPOINTS = ("exp3",)
# read only by the tests: a trained model (forward model C6, posture maps C2/C3) does not depend on them
TEST_KEYS = ("recog_set", "gen1_set", "gen2_set", "m1_centre_sigma", "match_threshold", "match_tolerance",
             "selection.max_steps", "posture.code_sigma", "quick.objects", "percept.looks", "selection.tau")


def ineffective_keys(cfg) -> dict[str, str]:
    out = {}
    if cfg.stimuli.kind == "folder":
        out.update({k: "stimuli=folder tests the user's folder only" for k in ("gen1_set", "gen2_set")})
    if cfg.preset == "quick":
        out["fm.images"] = "preset=quick trains on quick.fm_images"
    return {f"experiment.{k}": v for k, v in out.items()}
