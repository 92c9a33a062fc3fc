"""Stimulus sets, the edge pipeline and the eye (direct or pybullet camera path).

Typical use::

    from neuroimagery.vision import get_stimulus_set, make_eye, VisionConfig
    stim = get_stimulus_set("exp4-A")
    eye = make_eye(VisionConfig())
    target, rotated = eye.pair_edge_maps(stim, stim.pairs("A1"))   # (144, 32, 32) each
"""
from neuroimagery.vision.config import StimuliConfig, VisionConfig
from neuroimagery.vision.edges import (
    ROTATE_THRESHOLD,
    edge_pipeline,
    flip_main_axis,
    iou,
    mirror,
    principal_axis,
    red_mask,
    rotate,
    three_dot_images,
    three_dot_pairs,
)
from neuroimagery.vision.eye import CameraEye, DirectEye, Eye, make_eye
from neuroimagery.vision.stimulus_sets import (
    StimulusSet,
    get_stimulus_set,
    list_stimulus_sets,
    load_folder,
    resolve_stimulus_set,
    shape_elongation,
)

__all__ = [
    "VisionConfig",
    "StimuliConfig",
    "StimulusSet",
    "get_stimulus_set",
    "list_stimulus_sets",
    "load_folder",
    "resolve_stimulus_set",
    "shape_elongation",
    "Eye",
    "DirectEye",
    "CameraEye",
    "make_eye",
    "edge_pipeline",
    "red_mask",
    "rotate",
    "mirror",
    "flip_main_axis",
    "principal_axis",
    "iou",
    "three_dot_images",
    "three_dot_pairs",
    "ROTATE_THRESHOLD",
]
