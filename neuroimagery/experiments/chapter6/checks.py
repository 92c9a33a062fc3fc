"""Checks of Experiments 3 and 4 that run before any work (``neuroimagery.validation.check_run``):
the memory their settings need (:func:`memory_estimate`, compared by ``neuroimagery.core.resources``)
and the stimulus sets they name (:func:`check_inputs`).

The estimate counts the arrays that training must hold at once, float32:

- the forward models: Exp 3's C6 maps three image blocks onto one (``3 n x n`` weights), Exp 4's
  C1-C3 one block each (``3 x n x n``), per participant, with ``n = map_size^2``;
- the three-dot training set: inputs and targets of every image of every participant
  (Exp 3's inputs are three blocks wide).

Everything else (posture maps, stimulus banks) is smaller, so the figure is a lower bound.
"""
from __future__ import annotations

import difflib
import os

from ...core.errors import UserInputError
from ...core.resources import Need, culprit

FLOAT = 4  # bytes


def _images(cfg) -> tuple[str, int]:
    e = cfg.experiment
    return ("experiment.quick.fm_images", int(e.quick.fm_images)) if cfg.preset == "quick" \
        else ("experiment.fm.images", int(e.fm.images))


def memory_estimate(cfg) -> list[Need]:
    """The bytes of the forward models and of the three-dot training set (see the module docstring),
    each named by the setting furthest above its default."""
    e, P = cfg.experiment, int(cfg.participants)
    n = int(e.map_size) ** 2
    wide = 3 if e.name == "exp3" else 1  # Exp 3's C6 reads three image blocks
    key_images, images = _images(cfg)
    default_images = 3000 if cfg.preset == "quick" else 4000
    size = {"experiment.map_size": (e.map_size, 32), "participants": (P, 10)}
    return [Need(culprit(size), 3.0 * n * n * P * FLOAT, f"forward-model weights, {P} x 3 x {n}^2 floats"),
            Need(culprit({**size, key_images: (images, default_images)}), float(P) * images * (wide + 1) * n * FLOAT,
                 f"three-dot training set, {P} x {images} images x {(wide + 1) * n} floats")]


def check_set_name(key: str, name: str) -> None:
    """``name`` is a builtin stimulus set or a folder."""
    from ...vision.shapes import BUILTIN_GRIDS  # the builtin sets (vision.list_stimulus_sets), read without OpenCV

    known = list(BUILTIN_GRIDS)
    if name in known or os.path.isdir(name):
        return
    lower = {k.lower(): k for k in known}
    close = difflib.get_close_matches(name.lower(), list(lower), n=1)
    hint = f" (did you mean {lower[close[0]]!r}?)" if close else ""
    raise UserInputError(f"{key}={name!r} is not a stimulus set{hint}: not a folder, and not one of {', '.join(known)}")


def check_inputs(cfg) -> None:
    """Every stimulus set the run names exists, before any training."""
    e = cfg.experiment
    for key in ("train_set", "recog_set", "gen1_set", "gen2_set"):
        if hasattr(e, key):
            check_set_name(f"experiment.{key}", getattr(e, key))
