"""Stimulus sets of Experiments 1-4 and user folders of images.

A :class:`StimulusSet` names its objects, the orientations and appearances its protocol uses,
draws any (object, angle, appearance) as a red shape on a light background, and lists the
object pairs shown in a test:

* ``"L"`` (Exp. 1-2, sec. 5.1 D): objects A (an upside-down L) and B (its mirror image); the
  left object is rotated (the thesis tests 0 to +-90 degrees in steps of 15), the right one is
  shown at 0 degrees and is A or B.  Any angle can be drawn.
* ``"exp3-a"``, ``"exp3-b"``, ``"exp3-c"`` (Exp. 3, sec. 6.1.1 A): three objects each, at
  -90, -45, 0, 45 degrees, with the main or mirror appearance; each pair shows one object
  twice, so 2 x 2 appearances x 4 x 4 angles = 64 pairs per object.
* ``"exp4-A"``, ``"exp4-B"``, ``"exp4-C"`` (Exp. 4, sec. 6.2.1): three objects each, at 90, 60,
  30, 0, -30, -60 degrees, basic or mirror: 2 x 2 x 6 x 6 = 144 pairs per object.
* ``"exp3-b-v1"``, ``"exp3-c-v1"``, ``"exp4-A-v1"``, ``"exp4-B-v1"``, ``"exp4-C-v1"``: earlier
  designs of those sets (same protocol), kept to reproduce results obtained with them; they break
  some of the design rules of docs/stimuli.md (see :mod:`neuroimagery.vision.measure`);
* a folder of PNG/JPEG images, one shape per image, darker or redder than its background.

In a pair image the target object is on the left and the rotated object on the right (Exp. 3
and 4); in the ``"L"`` set the rotated object is on the left (Exp. 1-2).
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from neuroimagery.core.errors import UserInputError
from neuroimagery.vision.edges import principal_axis
from neuroimagery.vision.image_files import IMAGE_SUFFIXES, MAX_FOLDER_IMAGES, check_size, list_images, read_image
from neuroimagery.vision.shapes import (
    BACKGROUND_BGR,
    BUILTIN_GRIDS,
    CANVAS,
    CH6_RADIUS_FRACTION,
    RADIUS_FRACTION,
    Shape,
    colourise,
    grid_mask,
)

__all__ = [
    "StimulusSet",
    "get_stimulus_set",
    "list_stimulus_sets",
    "load_folder",
    "resolve_stimulus_set",
    "shape_elongation",
    "IMAGE_SUFFIXES",
]

PAIR_GAP = 0.25  # background between the two objects of a pair image, in canvas sides

_EXP3_ANGLES = [-90.0, -45.0, 0.0, 45.0]
_EXP4_ANGLES = [90.0, 60.0, 30.0, 0.0, -30.0, -60.0]
_L_ANGLES = [float(a) for a in range(-90, 91, 15)]


class StimulusSet:
    """Objects, protocol orientations and appearances; draws stimuli and lists test pairs.

    appearances[0] is the shape as designed, appearances[1] (if any) its mirror image.
    ``mirror_of`` maps an object to the object it mirrors (set "L": B -> A).
    ``radius_fraction``: the drawn size, the farthest point from the centroid as a fraction of
    the image side (:data:`~neuroimagery.vision.shapes.RADIUS_FRACTION` by default; the sets of
    Experiments 3 and 4 use :data:`~neuroimagery.vision.shapes.CH6_RADIUS_FRACTION`).
    """

    def __init__(
        self,
        name: str,
        shapes: dict[str, Shape],
        angles: Sequence[float],
        appearances: Sequence[str],
        protocol: str = "pairs",
        rotated_side: str = "right",
        radius_fraction: float = RADIUS_FRACTION,
    ):
        if not 0.0 < float(radius_fraction) <= 0.5:
            raise ValueError(f"radius_fraction must lie in (0, 0.5], got {radius_fraction}")
        if protocol not in ("pairs", "reference"):
            raise ValueError(f"protocol must be 'pairs' or 'reference', got {protocol!r}")
        self.name = name
        self._shapes = dict(shapes)
        self.objects: list[str] = list(shapes)
        self.angles: list[float] = [float(a) for a in angles]
        self.appearances: list[str] = list(appearances)
        self.protocol = protocol
        self.rotated_side = rotated_side
        self.radius_fraction = float(radius_fraction)

    def __repr__(self) -> str:
        return (f"StimulusSet({self.name!r}, objects={self.objects}, angles={self.angles}, "
                f"appearances={self.appearances})")

    def with_protocol(self, angles: Sequence[float], appearances: Sequence[str],
                      protocol: str = "pairs", rotated_side: str = "right",
                      radius_fraction: Optional[float] = None) -> "StimulusSet":
        """The same shapes under another experiment's orientations, appearance names and (if
        given) drawn size."""
        rf = self.radius_fraction if radius_fraction is None else radius_fraction
        return StimulusSet(self.name, self._shapes, angles, appearances, protocol, rotated_side, rf)

    # ------------------------------------------------------------------ drawing
    def shape(self, obj: str) -> Shape:
        if obj not in self._shapes:
            raise KeyError(f"set {self.name!r} has no object {obj!r}; objects: {self.objects}")
        return self._shapes[obj]

    def _is_mirror(self, appearance: str) -> bool:
        if appearance not in self.appearances:
            raise KeyError(f"set {self.name!r} has no appearance {appearance!r}; "
                           f"appearances: {self.appearances}")
        return self.appearances.index(appearance) == 1

    def coverage(self, obj: str, angle: float, appearance: Optional[str] = None,
                 canvas: int = CANVAS) -> np.ndarray:
        """Float coverage in [0, 1] of one object (anti-aliased), ``canvas x canvas``."""
        appearance = self.appearances[0] if appearance is None else appearance
        return self.shape(obj).render(angle, self._is_mirror(appearance), canvas, self.radius_fraction)

    def image(self, obj: str, angle: float, appearance: Optional[str] = None,
              canvas: int = CANVAS) -> np.ndarray:
        """BGR uint8 image ``(canvas, canvas, 3)``: the object, red on light grey, centred.

        angle in degrees, counter-clockwise positive, about the shape's centroid; any angle is
        allowed, not only the protocol's.
        """
        return colourise(self.coverage(obj, angle, appearance, canvas))

    def items(self) -> list[tuple[str, float, str]]:
        """Every (object, angle, appearance) of the protocol."""
        return list(itertools.product(self.objects, self.angles, self.appearances))

    # ------------------------------------------------------------------ pairs
    def pairs(self, obj: str) -> list[dict]:
        """The test pairs built from ``obj``, in a fixed order.

        Protocol "pairs" (Exp. 3-4): the object shown twice, every target appearance x rotated
        appearance x target angle x rotated angle.  Protocol "reference" (Exp. 1-2): ``obj`` at
        every protocol angle is rotated towards every object of the set shown at 0 degrees.
        ``same`` is True when the two shapes are identical up to rotation.
        """
        self.shape(obj)
        out = []
        if self.protocol == "pairs":
            for ta, ra, tang, rang in itertools.product(
                self.appearances, self.appearances, self.angles, self.angles
            ):
                out.append(dict(target_object=obj, target_angle=tang, target_appearance=ta,
                                rotated_object=obj, rotated_angle=rang, rotated_appearance=ra,
                                same=ta == ra))
        else:
            app = self.appearances[0]
            for target, rang in itertools.product(self.objects, self.angles):
                out.append(dict(target_object=target, target_angle=0.0, target_appearance=app,
                                rotated_object=obj, rotated_angle=rang, rotated_appearance=app,
                                same=target == obj))
        return out

    def pair_layout(self, canvas: int = CANVAS) -> tuple[tuple[int, int], float, float]:
        """(height, width) of a pair image and the x centres of the target and rotated object."""
        gap = int(round(PAIR_GAP * canvas))
        left, right = canvas / 2.0 - 0.5, canvas + gap + canvas / 2.0 - 0.5
        hw = (canvas, 2 * canvas + gap)
        return (hw, left, right) if self.rotated_side == "right" else (hw, right, left)

    def pair_image(self, pair: dict, canvas: int = CANVAS) -> np.ndarray:
        """BGR image of a pair on one screen: two ``canvas``-wide objects with a gap between."""
        (h, w), xt, xr = self.pair_layout(canvas)
        img = np.empty((h, w, 3), np.uint8)
        img[:] = BACKGROUND_BGR
        t = self.image(pair["target_object"], pair["target_angle"], pair["target_appearance"], canvas)
        r = self.image(pair["rotated_object"], pair["rotated_angle"], pair["rotated_appearance"], canvas)
        for im, xc in ((t, xt), (r, xr)):
            x0 = int(round(xc + 0.5 - canvas / 2.0))
            img[:, x0:x0 + canvas] = im
        return img


def shape_elongation(stimulus_set: StimulusSet, obj: str, canvas: int = 256) -> float:
    """Principal-axis ratio sqrt(lambda_max / lambda_min) of the filled object at 0 degrees."""
    return principal_axis(stimulus_set.coverage(obj, 0.0, None, canvas))[3]


# ---------------------------------------------------------------------- builtin sets
def _builtin(name: str) -> StimulusSet:
    grids = BUILTIN_GRIDS[name]
    shapes = {k: Shape(grid_mask(g), k) for k, g in grids.items()}
    if name == "L":
        shapes["B"] = shapes["A"].mirrored("B")
        return StimulusSet(name, shapes, _L_ANGLES, ["basic"], protocol="reference",
                           rotated_side="left")
    if name.startswith("exp3"):
        return StimulusSet(name, shapes, _EXP3_ANGLES, ["main", "mirror"], radius_fraction=CH6_RADIUS_FRACTION)
    return StimulusSet(name, shapes, _EXP4_ANGLES, ["basic", "mirror"], radius_fraction=CH6_RADIUS_FRACTION)


_CACHE: dict[str, StimulusSet] = {}


def list_stimulus_sets() -> list[str]:
    """Names of the builtin stimulus sets."""
    return list(BUILTIN_GRIDS)


def get_stimulus_set(name_or_path: str) -> StimulusSet:
    """A builtin set by name, or a user folder of images (see :func:`load_folder`).

    Unknown names raise :class:`~neuroimagery.core.errors.UserInputError` (a ValueError) listing
    the valid ones.
    """
    name_or_path = str(name_or_path)
    if name_or_path in BUILTIN_GRIDS:
        if name_or_path not in _CACHE:
            _CACHE[name_or_path] = _builtin(name_or_path)
        return _CACHE[name_or_path]
    if os.path.isdir(name_or_path):
        return load_folder(name_or_path)
    raise UserInputError(
        f"unknown stimulus set {name_or_path!r}: not a folder, and not one of "
        f"{', '.join(list_stimulus_sets())}"
    )


def resolve_stimulus_set(stimuli_cfg, builtin: str) -> StimulusSet:
    """The set an experiment tests on: ``builtin``, or the user folder of ``stimuli_cfg``.

    A folder set takes the protocol (angles, appearance names, pairing) and the drawn size of
    the builtin set it replaces, so the experiment's counts and conditions stay the same.
    """
    base = get_stimulus_set(builtin)
    if getattr(stimuli_cfg, "kind", "builtin") == "builtin":
        return base
    path = getattr(stimuli_cfg, "path", None)
    if not path or not os.path.isdir(path):
        raise UserInputError(f"stimuli.path {path!r} is not a folder")
    appearances = base.appearances if len(base.appearances) == 2 else ["basic", "mirror"]
    return load_folder(path).with_protocol(base.angles, appearances, radius_fraction=base.radius_fraction)


# ---------------------------------------------------------------------- user folders
def _foreground(image: np.ndarray, file: Path, transparent: bool = False) -> np.ndarray:
    """Mask of the single shape in a user image: pixels darker or redder than the background.
    ``transparent``: the image's alpha channel varies, named when no shape is found in its colours."""
    try:
        return _colour_foreground(image, file)
    except UserInputError as err:
        if not transparent:
            raise
        raise UserInputError(f"{err} (the image is transparent in places and its colours are read without "
                             "the transparency: a shape drawn only in the alpha channel is not seen; flatten "
                             "the image onto a white background)") from None


def _colour_foreground(image: np.ndarray, file: Path) -> np.ndarray:
    img = image.astype(np.float32)
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = np.median(border, axis=0)
    luma = img @ np.float32([0.114, 0.587, 0.299])
    bg_luma = float(bg @ np.float32([0.114, 0.587, 0.299]))
    redness = img[..., 2] - np.maximum(img[..., 0], img[..., 1])
    bg_red = float(bg[2] - max(bg[0], bg[1]))
    score = np.maximum(bg_luma - luma, redness - bg_red)
    if score.max() < 40.0:
        raise UserInputError(f"no shape found in {file}: nothing is clearly darker or redder "
                             "than the background")
    thr, _ = cv2.threshold(np.clip(score, 0, 255).astype(np.uint8), 0, 255,
                           cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = (score > max(thr, 20.0)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        raise UserInputError(f"no shape found in {file}")
    areas = stats[1:, cv2.CC_STAT_AREA]
    big = 1 + int(np.argmax(areas))
    if areas.max() < max(16, 1e-4 * mask.size):
        raise UserInputError(f"no shape found in {file}: the darker/redder region is too small")
    shape = (labels == big).astype(np.uint8)
    # fill holes: a shape is its outer outline
    contours, _ = cv2.findContours(shape, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(shape)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return filled


def load_folder(path: str | os.PathLike) -> StimulusSet:
    """A stimulus set from a folder of PNG/JPEG images, one shape per image.

    Objects are named after the files (sorted); each shape is the largest region darker or
    redder than the image border, holes filled, then drawn red like the builtin shapes.  The
    default protocol is Experiment 4's (6 angles, basic/mirror); :func:`resolve_stimulus_set`
    or :meth:`StimulusSet.with_protocol` give another.  Errors name the folder or the file.
    """
    folder = Path(path)
    if not folder.is_dir():
        raise UserInputError(f"stimulus folder {folder} does not exist or is not a folder")
    files = list_images(folder)
    if not files:
        raise UserInputError(f"stimulus folder {folder} contains no PNG or JPEG images")
    if len(files) > MAX_FOLDER_IMAGES:
        raise UserInputError(f"stimulus folder {folder} holds {len(files)} images; at most {MAX_FOLDER_IMAGES}")
    for f in files:  # every size from the headers before anything is decoded
        check_size(f)
    shapes: dict[str, Shape] = {}
    for f in files:
        img, transparent = read_image(f)
        name = f.stem
        if name in shapes:
            name = f.name
        shapes[name] = Shape(_foreground(img, f, transparent), name)
    return StimulusSet(folder.name or str(folder), shapes, _EXP4_ANGLES, ["basic", "mirror"])
