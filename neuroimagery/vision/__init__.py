"""Stimulus sets, the edge pipeline and the eye (direct or pybullet camera path).

Typical use::

    from neuroimagery.vision import get_stimulus_set, make_eye, VisionConfig
    stim = get_stimulus_set("exp4-A")
    eye = make_eye(VisionConfig())
    target, rotated = eye.pair_edge_maps(stim, stim.pairs("A1"))   # (144, 32, 32) each

The names of :mod:`.stimulus_sets`, :mod:`.eye` and :mod:`.edges` are imported on first use, so
that the configuration (:mod:`.config`) is read without OpenCV and torch.
"""
from __future__ import annotations

import importlib
from pathlib import Path

from neuroimagery.vision.config import StimuliConfig, VisionConfig

_EXPORTING = ("stimulus_sets", "eye", "edges")  # the modules whose ``__all__`` this package exports


def __getattr__(name: str):
    if (Path(__file__).parent / f"{name}.py").is_file():  # a module of the package
        return importlib.import_module(f"{__name__}.{name}")
    if name.startswith("__") and name != "__all__":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    exported = {"VisionConfig": VisionConfig, "StimuliConfig": StimuliConfig}
    for m in _EXPORTING:
        module = importlib.import_module(f"{__name__}.{m}")
        exported.update({n: getattr(module, n) for n in module.__all__})
    globals().update(exported, __all__=list(exported))
    if name in globals():
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
