"""Hydra schemas of the `vision` and `stimuli` config groups."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


def _check_range(name: str, value: float, low: float, high: float) -> None:
    if not (low <= value <= high):
        raise ValueError(f"vision.{name} must lie in [{low}, {high}], got {value!r}")


@dataclass
class VisionConfig:
    """How the model sees a stimulus pair.

    kind: ``direct`` draws the pair and runs the edge pipeline on it; ``camera`` renders the
    screen seen through the iCub's eye in pybullet first.

    The photometric keys (``luminance`` ... ``noise_std``) act on whatever image the eye sees, in
    both paths; ``gaze_jitter_deg`` only exists for the camera path (the eye motors).
    """

    kind: str = "direct"
    size: int = 32  # side of the binary edge map fed to the model (thesis: 32x32)
    red_threshold: float = 60.0  # grey levels by which R must exceed max(G, B) to count as red, (0, 255)
    # --- varying camera images (robot camera response, room light) ---
    luminance: float = 1.0  # global gain on the image intensities, (0, 3]; 1 = as drawn
    luminance_jitter: float = 0.0  # sd of a per-image log-normal gain change, [0, 1]
    gamma: float = 1.0  # camera response curve I_out = 255 (I_in/255)^gamma, [0.2, 5]
    noise_std: float = 0.0  # sd of Gaussian per-pixel sensor noise in grey levels, [0, 100]
    seed: int = 0  # seed of the eye's own noise generator, >= 0
    # --- camera path only (pybullet, TinyRenderer) ---
    robot_model: str = "iCubGazeboV2_5"  # icub-models robot whose URDF gives the head chain
    eye: str = "left"  # which eye's camera sees the screen: left | right
    image_width: int = 640  # camera image width in pixels (the iCub's cameras: 640x480), [64, 2048]
    image_height: int = 480  # camera image height in pixels, [48, 2048]
    fov_deg: float = 30.0  # vertical field of view of the eye camera in degrees, [10, 120]
    screen_distance: float = 0.8  # metres from the eyes to the screen, [0.2, 3]
    object_width: float = 0.12  # metres of screen per object cell (one object's square), [0.02, 1]
    gaze_jitter_deg: float = 0.0  # sd of the eye pan/tilt error in degrees (motor accuracy), [0, 5]

    def __post_init__(self) -> None:
        if self.kind not in ("direct", "camera"):
            raise ValueError(f"vision.kind must be 'direct' or 'camera', got {self.kind!r}")
        if self.size < 8:
            raise ValueError(f"vision.size must be >= 8, got {self.size}")
        if self.eye not in ("left", "right"):
            raise ValueError(f"vision.eye must be 'left' or 'right', got {self.eye!r}")
        if not (0.0 < self.red_threshold < 255.0):
            raise ValueError(f"vision.red_threshold must lie in (0, 255), got {self.red_threshold!r}")
        if not (0.0 < self.luminance <= 3.0):
            raise ValueError(f"vision.luminance must lie in (0, 3], got {self.luminance!r}")
        _check_range("luminance_jitter", self.luminance_jitter, 0.0, 1.0)
        _check_range("gamma", self.gamma, 0.2, 5.0)
        _check_range("noise_std", self.noise_std, 0.0, 100.0)
        if self.seed < 0:
            raise ValueError(f"vision.seed must be >= 0, got {self.seed}")
        _check_range("image_width", self.image_width, 64, 2048)
        _check_range("image_height", self.image_height, 48, 2048)
        _check_range("fov_deg", self.fov_deg, 10.0, 120.0)
        _check_range("screen_distance", self.screen_distance, 0.2, 3.0)
        _check_range("object_width", self.object_width, 0.02, 1.0)
        _check_range("gaze_jitter_deg", self.gaze_jitter_deg, 0.0, 5.0)


@dataclass
class StimuliConfig:
    """Which stimuli the tests use: the thesis's sets (``builtin``) or a user's folder."""

    kind: str = "builtin"
    path: Optional[str] = None  # folder of PNG/JPEG images, with kind=folder

    def __post_init__(self) -> None:
        if self.kind not in ("builtin", "folder"):
            raise ValueError(f"stimuli.kind must be 'builtin' or 'folder', got {self.kind!r}")
        if self.kind == "folder" and not self.path:
            raise ValueError("stimuli.path must name a folder when stimuli=folder")
