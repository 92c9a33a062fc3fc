"""The model's eye: stimulus images -> binary edge maps, by the direct or the camera path.

Both paths show the stimulus as it would appear on the screen (a single object in the target's
place, or the whole pair), apply the photometric model of a real camera, and run
:func:`~neuroimagery.vision.edges.edge_pipeline` on a view centred on the object looked at:

* direct: the drawn pair image itself; looking at an object = taking the image region around
  its place on the screen;
* camera: the image of the iCub's eye camera in pybullet, gazing at the object
  (see :mod:`neuroimagery.vision.camera`).

Photometric model (per image, thesis sec. 6 intro: light and camera response vary):
``I' = clip(255 * (g * I / 255) ** gamma + n)``, ``g = luminance * exp(luminance_jitter * z)``,
``z ~ N(0, 1)`` per image, ``n ~ N(0, noise_std^2)`` per pixel and channel.
"""
from __future__ import annotations

from typing import Optional, Sequence

import cv2
import numpy as np
import torch

from neuroimagery.vision.config import VisionConfig
from neuroimagery.vision.edges import edge_pipeline
from neuroimagery.vision.shapes import BACKGROUND_BGR, CANVAS
from neuroimagery.vision.stimulus_sets import StimulusSet

__all__ = ["Eye", "DirectEye", "CameraEye", "make_eye"]

Item = tuple[str, float, str]


class Eye:
    """Base class: photometric model and the shared edge pipeline; subclasses give the views."""

    def __init__(self, cfg: VisionConfig):
        self.cfg = cfg
        # The photometric noise (luminance jitter, sensor noise, gaze jitter) comes from this
        # generator, seeded from ``vision.seed`` only: not from the run's ``seed`` nor from the
        # participant (all participants see the same maps). Every new eye replays the same stream,
        # so the k-th image an eye sees gets the same noise draw in every eye. The experiments make
        # a fresh eye per phase (Exp. 3-4: training, then testing; Exp. 1-2: every batch of edge
        # maps), so with the noise on, a test batch that shows the training stimuli in the training
        # order (the Recog set of Exp. 3-4, the 14 images of Exp. 2) gets exactly the training
        # images, noise included. The noise is off by default (luminance_jitter = noise_std = 0).
        self.rng = np.random.default_rng(cfg.seed)

    # --------------------------------------------------------------- photometry
    def photometric(self, images: np.ndarray) -> np.ndarray:
        """Apply luminance gain, camera response and sensor noise to BGR images (N, H, W, 3)."""
        cfg = self.cfg
        if self._photometry_off():
            return images
        x = images.astype(np.float32) / 255.0
        gain = cfg.luminance * np.exp(cfg.luminance_jitter * self.rng.standard_normal(len(x)))
        x = np.clip(x * gain[:, None, None, None].astype(np.float32), 0.0, 1.0) ** cfg.gamma
        x = 255.0 * x
        if cfg.noise_std > 0:
            x = x + cfg.noise_std * self.rng.standard_normal(x.shape, dtype=np.float32)
        return np.clip(np.round(x), 0, 255).astype(np.uint8)

    def reset_state(self, seed: Optional[int] = None) -> None:
        """Restart the noise generator (from ``seed`` or the config's)."""
        self.rng = np.random.default_rng(self.cfg.seed if seed is None else seed)

    # --------------------------------------------------------------- views
    def _views(self, stimulus_set: StimulusSet, screens: list[np.ndarray],
               gazes: list[float]) -> tuple[list[np.ndarray], float]:
        """Images seen when looking at column ``gazes[i]`` of ``screens[i]``, and the window."""
        raise NotImplementedError

    def _screens(self, stimulus_set: StimulusSet, pairs: Sequence[dict]) -> list[np.ndarray]:
        return [stimulus_set.pair_image(pr) for pr in pairs]

    def edge_maps(self, stimulus_set: StimulusSet, items: Sequence[Item],
                  size: Optional[int] = None, gaze_errors: Optional[np.ndarray] = None) -> torch.Tensor:
        """Edge maps ``(N, size, size)`` of single objects, each shown in the target's place.

        ``gaze_errors``: optional ``(N, 2)`` errors of the look at each item, (pan, tilt) in degrees:
        the view moves by the screen distance they span (direct path: ``CANVAS`` pixels per
        ``object_width``), sampled at that offset (bilinear), not rounded to whole pixels: the eye's
        pixels do not line up with the screen's (docs/choices.md, rule R4)."""
        size = self.cfg.size if size is None else size
        (h, w), xt, _ = stimulus_set.pair_layout()
        x0 = int(round(xt + 0.5 - CANVAS / 2.0))
        screens = []
        for image in self._item_images(stimulus_set, items, gaze_errors):
            screen = np.empty((h, w, 3), np.uint8)
            screen[:] = BACKGROUND_BGR
            screen[:, x0:x0 + CANVAS] = image
            screens.append(screen)
        views, window = self._views(stimulus_set, screens, [xt] * len(screens))
        return edge_pipeline(views, size, window, self.cfg.red_threshold)

    def _item_images(self, stimulus_set: StimulusSet, items: Sequence[Item],
                     gaze_errors: Optional[np.ndarray] = None) -> list[np.ndarray]:
        """The ``CANVAS``-wide image of each item as the eye sees it on the screen: moved against
        its gaze error (``(N, 2)`` deg, pan and tilt) where given; an item looked at several times
        is drawn once."""
        drawn, out = {}, []
        for k, item in enumerate(items):
            if item not in drawn:
                drawn[item] = stimulus_set.image(*item)
            image = drawn[item]
            if gaze_errors is not None:  # the eye looks off by (pan, tilt): the object moves the other way
                dx, dy = np.tan(np.radians(gaze_errors[k])) * self.cfg.screen_distance / self.cfg.object_width * CANVAS
                image = _shifted(image, -float(dx), -float(dy))
            out.append(image)
        return out

    def _photometric_list(self, images: list[np.ndarray]) -> list[np.ndarray]:
        """:meth:`photometric` of a list of images, the list itself where it changes nothing."""
        return images if self._photometry_off() else list(self.photometric(np.stack(images)))

    def _photometry_off(self) -> bool:
        """Whether the photometric model leaves every image as it is (the default)."""
        cfg = self.cfg
        return cfg.luminance == 1.0 and cfg.luminance_jitter == 0.0 and cfg.gamma == 1.0 and cfg.noise_std == 0.0

    def pair_edge_maps(self, stimulus_set: StimulusSet, pairs: Sequence[dict],
                       size: Optional[int] = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(target maps, rotated maps), each ``(N, size, size)``, seeing each pair on one screen.

        The gaze goes to the target object, then to the rotated object (hard-wired order).
        """
        size = self.cfg.size if size is None else size
        _, xt, xr = stimulus_set.pair_layout()
        screens = self._screens(stimulus_set, pairs)
        tv, window = self._views(stimulus_set, screens, [xt] * len(screens))
        rv, window_r = self._views(stimulus_set, screens, [xr] * len(screens))
        target = edge_pipeline(tv, size, window, self.cfg.red_threshold)
        rotated = edge_pipeline(rv, size, window_r, self.cfg.red_threshold)
        return target, rotated

    def close(self) -> None:
        """Release resources (the pybullet client of the camera path)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _shifted(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``image`` moved by ``(dx, dy)`` pixels, sampled bilinearly, the uncovered border background."""
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(image, m, (image.shape[1], image.shape[0]), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=tuple(int(b) for b in BACKGROUND_BGR))


class DirectEye(Eye):
    """The drawn image itself: looking at an object = the canvas-sized region around it."""

    def _views(self, stimulus_set, screens, gazes):
        views = []
        for screen, x in zip(screens, gazes):
            h = screen.shape[0]
            x0 = int(round(x + 0.5 - h / 2.0))
            views.append(screen[:, x0:x0 + h])
        return self._photometric_list(views), float(CANVAS)

    def edge_maps(self, stimulus_set, items, size=None, gaze_errors=None):
        (h, _), xt, _ = stimulus_set.pair_layout()
        x0 = int(round(xt + 0.5 - CANVAS / 2.0))
        if h != CANVAS or x0 != int(round(xt + 0.5 - h / 2.0)):  # a view wider than the object's place
            return super().edge_maps(stimulus_set, items, size, gaze_errors)
        # the view of the target's place on a screen that shows one object there is that object's image
        views = self._photometric_list(self._item_images(stimulus_set, items, gaze_errors))
        return edge_pipeline(views, self.cfg.size if size is None else size, float(CANVAS), self.cfg.red_threshold)


class CameraEye(Eye):
    """The iCub's eye camera in pybullet (DIRECT, TinyRenderer) looking at the screen."""

    def __init__(self, cfg: VisionConfig):
        super().__init__(cfg)
        self._scene = None
        self._layout = None

    def scene(self, stimulus_set: StimulusSet):
        """The pybullet scene for this set's pair layout (built once, rebuilt if it changes)."""
        from neuroimagery.vision.camera import CameraScene

        (hw, xt, xr) = layout = stimulus_set.pair_layout()
        if self._scene is None or self._layout != layout:
            self.close()
            self._scene = CameraScene(self.cfg, hw, (xt, xr), CANVAS)
            self._layout = layout
        return self._scene

    def _look(self, scene, x: float, gaze: dict, error=None) -> np.ndarray:
        """Render the eye's image when gazing at slot ``x`` (hard-wired posture + motor error;
        ``error``: a given (pan, tilt) error in degrees)."""
        if x not in gaze:
            gaze[x] = scene.gaze_angles(scene.screen_point(x))
        tilt, pan = gaze[x]
        if error is not None:
            pan, tilt = pan + np.radians(float(error[0])), tilt + np.radians(float(error[1]))
        jitter = np.radians(self.cfg.gaze_jitter_deg)
        if jitter > 0:
            tilt += jitter * self.rng.standard_normal()
            pan += jitter * self.rng.standard_normal()
        return scene.render(tilt, pan)

    def edge_maps(self, stimulus_set, items, size=None, gaze_errors=None):
        size = self.cfg.size if size is None else size
        scene = self.scene(stimulus_set)
        _, xt, _ = stimulus_set.pair_layout()
        gaze: dict = {}
        views = []
        for k, item in enumerate(items):
            scene.show(stimulus_set, {xt: tuple(item)})
            views.append(self._look(scene, xt, gaze, None if gaze_errors is None else gaze_errors[k]))
        window = scene.window_px(scene.screen_point(xt))
        return edge_pipeline(self.photometric(np.stack(views)), size, window, self.cfg.red_threshold)

    def pair_edge_maps(self, stimulus_set, pairs, size=None):
        size = self.cfg.size if size is None else size
        scene = self.scene(stimulus_set)
        _, xt, xr = stimulus_set.pair_layout()
        gaze: dict = {}
        tv, rv = [], []
        for pr in pairs:
            scene.show(stimulus_set, {
                xt: (pr["target_object"], pr["target_angle"], pr["target_appearance"]),
                xr: (pr["rotated_object"], pr["rotated_angle"], pr["rotated_appearance"])})
            tv.append(self._look(scene, xt, gaze))  # first the target ...
            rv.append(self._look(scene, xr, gaze))  # ... then the rotated object
        wt = scene.window_px(scene.screen_point(xt))
        wr = scene.window_px(scene.screen_point(xr))
        target = edge_pipeline(self.photometric(np.stack(tv)), size, wt, self.cfg.red_threshold)
        rotated = edge_pipeline(self.photometric(np.stack(rv)), size, wr, self.cfg.red_threshold)
        return target, rotated

    def close(self) -> None:
        if self._scene is not None:
            self._scene.close()
            self._scene = None


def make_eye(vision_cfg: VisionConfig) -> Eye:
    """The eye selected by ``vision_cfg.kind`` ("direct" or "camera")."""
    if vision_cfg.kind == "direct":
        return DirectEye(vision_cfg)
    if vision_cfg.kind == "camera":
        return CameraEye(vision_cfg)
    raise ValueError(f"vision.kind must be 'direct' or 'camera', got {vision_cfg.kind!r}")
