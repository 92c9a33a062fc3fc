"""Experiment 4's schema (``experiment.*``) and what the checks before any work read of it
(:mod:`neuroimagery.validation`, :mod:`neuroimagery.core.manifest`; the memory estimate and the
stimulus sets: :mod:`..chapter6.checks`): nothing heavy is imported here."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List

from ...core.bounds import bounded
from ...models.rotation_embodied_params import EmbodiedParams
from ..chapter6.config import PerceptParams, QuickParams

TESTS = ("recog", "gen1", "gen2")


@dataclass
class Exp4Config(EmbodiedParams):
    """The model's parameters (:class:`EmbodiedParams`) and the run's: the stimulus sets, what
    ``preset=quick`` shrinks."""

    name: str = "exp4"
    train_set: str = "exp4-A"  # set whose images train C16/C17 (thesis: set A)
    recog_set: str = "exp4-A"  # Recog test set
    gen1_set: str = "exp4-B"  # Gen1 test set
    gen2_set: str = "exp4-C"  # Gen2 test set
    noise_tests: List[str] = bounded(factory=lambda: ["recog", "gen1"], choices=TESTS, each=True)  # tests repeated with noise
    quick: QuickParams = field(default_factory=QuickParams)  # objects per test set (full: all 3), images
    percept: PerceptParams = field(default_factory=PerceptParams)  # how the percept varies (rule R4)


CONFIG = Exp4Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.core.manifest)
INPUTS = ("vision", "stimuli")
CHECKPOINTS = ("exp4",)
# read only by the tests: a trained model (forward models, posture maps C16/C17) does not depend on them
TEST_KEYS = ("recog_set", "gen1_set", "gen2_set", "posture.tau", "ppc.sigma", "selection.tau",
             "selection.max_steps", "ppc.proprio_gain", "ppc.noise_amplitude", "noise_tests", "quick.objects", "percept.looks")


def ineffective_keys(cfg) -> dict[str, str]:
    e, out = cfg.experiment, {"lca.k": "PMCd's leak is set per participant after training (rule R2, docs/choices.md)"}
    if cfg.stimuli.kind == "folder":
        out.update({k: "stimuli=folder tests the user's folder only" for k in ("gen1_set", "gen2_set", "noise_tests")})
    elif not e.noise_tests:
        out["ppc.noise_amplitude"] = "noise_tests is empty"
    if cfg.preset == "quick":
        out["fm.images"] = "preset=quick trains on quick.fm_images"
    return {f"experiment.{k}": v for k, v in out.items()}
