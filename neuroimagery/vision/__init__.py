"""Stimulus sets, the edge pipeline and the eye (direct or pybullet camera path).

Typical use::

    from neuroimagery.vision import get_stimulus_set, make_eye, VisionConfig
    stim = get_stimulus_set("exp4-A")
    eye = make_eye(VisionConfig())
    target, rotated = eye.pair_edge_maps(stim, stim.pairs("A1"))   # (144, 32, 32) each
"""
from neuroimagery.vision import edges, eye, stimulus_sets
from neuroimagery.vision.config import StimuliConfig, VisionConfig
from neuroimagery.vision.edges import *  # noqa: F401,F403  (names listed in edges.__all__)
from neuroimagery.vision.eye import *  # noqa: F401,F403
from neuroimagery.vision.stimulus_sets import *  # noqa: F401,F403

__all__ = ["VisionConfig", "StimuliConfig", *stimulus_sets.__all__, *eye.__all__, *edges.__all__]
