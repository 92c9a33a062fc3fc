"""Hydra schemas of the `vision` and `stimuli` config groups."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ..core.bounds import Rule, bounded, check_declared


@dataclass
class VisionConfig:
    """How the model sees a stimulus pair.

    kind: ``direct`` draws the pair and runs the edge pipeline on it; ``camera`` renders the
    screen seen through the iCub's eye in pybullet first.

    The photometric keys (``luminance`` ... ``noise_std``) act on whatever image the eye sees, in
    both paths; ``gaze_jitter_deg`` only exists for the camera path (the eye motors).
    """

    kind: str = bounded("direct", choices=("direct", "camera"))
    size: int = bounded(32, ge=8)  # side of the binary edge map fed to the model (thesis: 32x32)
    red_threshold: float = bounded(60.0, gt=0, lt=255)  # grey levels by which R must exceed max(G, B) to count as red, (0, 255)
    # --- varying camera images (robot camera response, room light) ---
    luminance: float = bounded(1.0, gt=0, le=3)  # global gain on the image intensities, (0, 3]; 1 = as drawn
    luminance_jitter: float = bounded(0.0, ge=0, le=1)  # sd of a per-image log-normal gain change, [0, 1]
    gamma: float = bounded(1.0, ge=0.2, le=5)  # camera response curve I_out = 255 (I_in/255)^gamma, [0.2, 5]
    noise_std: float = bounded(0.0, ge=0, le=100)  # sd of Gaussian per-pixel sensor noise in grey levels, [0, 100]
    seed: int = bounded(0, ge=0)  # seed of the eye's own noise generator, >= 0
    # --- camera path only (pybullet, TinyRenderer) ---
    robot_model: str = "iCubGazeboV2_5"  # icub-models robot whose URDF gives the head chain
    eye: str = bounded("left", choices=("left", "right"))  # which eye's camera sees the screen: left | right
    image_width: int = bounded(640, ge=64, le=2048)  # camera image width in pixels (the iCub's cameras: 640x480), [64, 2048]
    image_height: int = bounded(480, ge=48, le=2048)  # camera image height in pixels, [48, 2048]
    fov_deg: float = bounded(30.0, ge=10, le=120)  # vertical field of view of the eye camera in degrees, [10, 120]
    screen_distance: float = bounded(0.8, ge=0.2, le=3)  # metres from the eyes to the screen, [0.2, 3]
    object_width: float = bounded(0.12, ge=0.02, le=1)  # metres of screen per object cell (one object's square), [0.02, 1]
    gaze_jitter_deg: float = bounded(0.0, ge=0, le=5)  # sd of the eye pan/tilt error in degrees (motor accuracy), [0, 5]

    def __post_init__(self) -> None:
        check_declared(self, "vision.")


@dataclass
class StimuliConfig:
    """Which stimuli the tests use: the thesis's sets (``builtin``) or a user's folder."""

    kind: str = bounded("builtin", choices=("builtin", "folder"))
    path: Optional[str] = None  # folder of PNG/JPEG images, with kind=folder

    RULES = (Rule("path", lambda s: s.kind != "folder" or bool(s.path), "must name a folder when stimuli=folder",
                  show=False),)

    def __post_init__(self) -> None:
        check_declared(self, "stimuli.")
