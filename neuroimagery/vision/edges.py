"""Early vision: from a colour image to the binary edge map the model's visual maps receive.

The pipeline (thesis sec. 5.1 D, 6.1.1 A):

1. red colour filter: a pixel is red when ``R - max(G, B) > red_threshold``, after a 5x5
   Gaussian blur that keeps sensor noise from fraying the outline;
2. centre on one object: the red blob nearest the gaze point (the image centre) is taken, with
   any other blob whose centre lies inside the same window (a shape split by noise); the crop
   is a ``window`` x ``window`` square about the blob's centroid, resampled to ``K * size``
   pixels (``K = 4``) so that the centroid falls on the map's centre ``((size - 1) / 2)``;
3. Canny edge detection (OpenCV) on the binarised crop;
4. reduction to ``size x size``: a map unit is 1 when any edge pixel falls in its K x K block.

Map operations used by the models (all about the map centre ``c = ((W-1)/2, (H-1)/2)``):
``rotate`` (cv2.warpAffine, bilinear, re-binarised at ``ROTATE_THRESHOLD``), ``mirror``
(left-right reflection), ``flip_main_axis`` (reflection of each map about its own principal
axis) and ``iou``.  Angles are in degrees, positive counter-clockwise as seen on the image.
"""
from __future__ import annotations

from typing import Sequence, Union

import cv2
import numpy as np
import torch

__all__ = [
    "SUPERSAMPLE",
    "ROTATE_THRESHOLD",
    "red_mask",
    "edge_pipeline",
    "rotate",
    "mirror",
    "flip_main_axis",
    "principal_axis",
    "iou",
    "three_dot_images",
    "three_dot_centres",
    "three_dot_maps",
    "three_dot_pairs",
]

SUPERSAMPLE = 4  # Canny runs on a (K*size)^2 crop; K x K pixel blocks become one map unit
ROTATE_THRESHOLD = 0.5  # a warped map unit is on when its bilinear value is >= this
_CANNY_LOW, _CANNY_HIGH = 100, 200  # the crop is binary (0/255): any pair in (0, 1000) agrees


def _as_batch(images: Union[np.ndarray, Sequence[np.ndarray]]) -> list[np.ndarray]:
    if isinstance(images, np.ndarray):
        if images.ndim == 3:
            images = images[None]
        if images.ndim != 4 or images.shape[-1] != 3:
            raise ValueError(f"expected BGR images of shape (N, H, W, 3), got {images.shape}")
        return list(images)
    out = list(images)
    for im in out:
        if im.ndim != 3 or im.shape[-1] != 3:
            raise ValueError(f"expected a BGR image of shape (H, W, 3), got {im.shape}")
    return out


def red_mask(image_bgr: np.ndarray, red_threshold: float = 60.0) -> np.ndarray:
    """Binary (uint8 0/1) mask of the red pixels: ``R - max(G, B) > red_threshold``.

    A chromatic difference rather than a hue test: it keeps working when the whole image gets
    darker or brighter (the gain scales the difference, not its sign).
    """
    im = image_bgr.astype(np.int16)
    redness = im[..., 2] - np.maximum(im[..., 0], im[..., 1])
    return (redness > red_threshold).astype(np.uint8)


def _object_centre(mask: np.ndarray, window: float, gaze: tuple[float, float]):
    """Centroid of the object nearest the gaze point, and the mask restricted to it."""
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None, mask
    areas = stats[1:, cv2.CC_STAT_AREA].astype(np.float64)
    keep = np.flatnonzero(areas >= max(3.0, 0.1 * areas.max())) + 1  # drop noise specks
    d = np.hypot(cents[keep, 0] - gaze[0], cents[keep, 1] - gaze[1])
    seed = keep[np.argmin(d)]
    near = keep[np.max(np.abs(cents[keep] - cents[seed]), axis=1) < window / 2]
    if len(near) == 1:  # one object: OpenCV's centroid of it is the mean of its pixels' coordinates
        return (cents[near[0], 0], cents[near[0], 1]), (labels == near[0]).view(np.uint8)
    sel = np.isin(labels, near)
    ys, xs = np.nonzero(sel)
    return (xs.mean(), ys.mean()), sel.view(np.uint8)


def edge_pipeline(
    images_bgr: Union[np.ndarray, Sequence[np.ndarray]],
    size: int = 32,
    window: float | None = None,
    red_threshold: float = 60.0,
) -> torch.Tensor:
    """Binary edge maps ``(N, size, size)`` (float 0/1) of the object nearest each image's centre.

    window: side in image pixels of the square around the object that becomes the map (the
    scale of the map); default: the smaller image side.  An image with no red object gives an
    all-zero map.
    """
    batch = _as_batch(images_bgr)
    k = SUPERSAMPLE
    side = k * size
    edges = np.zeros((len(batch), side, side), bool)
    for i, im in enumerate(batch):
        crop = _crop(im, side, window, red_threshold)
        if crop is not None:
            binary = np.where(crop >= 0.5, 255, 0).astype(np.uint8)
            edges[i] = cv2.Canny(binary, _CANNY_LOW, _CANNY_HIGH) > 0
    # a map unit is on when any edge pixel falls in its K x K block
    pooled = edges.reshape(len(batch), size, k, size, k).any(axis=(2, 4))
    return torch.from_numpy(pooled).float()


def _crop(im: np.ndarray, side: int, window: float | None, red_threshold: float) -> np.ndarray | None:
    """The red object nearest the centre of ``im``, its centroid at the centre of a ``side`` x
    ``side`` float crop of the ``window`` about it (bilinear); None when there is no red object."""
    h, w = im.shape[:2]
    win = float(window if window is not None else min(h, w))
    mask = red_mask(cv2.GaussianBlur(im, (5, 5), 0), red_threshold)
    centre, mask = _object_centre(mask, win, ((w - 1) / 2.0, (h - 1) / 2.0))
    if centre is None:
        return None
    scale = side / win
    src = mask.astype(np.float32)
    cx, cy = centre
    if scale < 0.5:  # pre-shrink by area averaging so bilinear sampling does not alias
        f = 2.0 * scale
        src = cv2.resize(src, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        fx, fy = src.shape[1] / w, src.shape[0] / h
        cx, cy, scale = (cx + 0.5) * fx - 0.5, (cy + 0.5) * fy - 0.5, scale / f
    c_out = (side - 1) / 2.0
    m = np.float32([[scale, 0, c_out - scale * cx], [0, scale, c_out - scale * cy]])
    return cv2.warpAffine(src, m, (side, side), flags=cv2.INTER_LINEAR)


def _flat_maps(maps: torch.Tensor) -> tuple[np.ndarray, tuple]:
    if maps.dim() < 2:
        raise ValueError(f"maps must have shape (..., H, W), got {tuple(maps.shape)}")
    shape = tuple(maps.shape)
    flat = maps.detach().reshape(-1, shape[-2], shape[-1]).cpu().numpy()
    return np.asarray(flat, dtype=np.float32), shape  # float32 maps are read as they are (never written)


def _warp_all(arr: np.ndarray, mats: list[np.ndarray], threshold: float) -> np.ndarray:
    """Each map of ``arr`` warped by its matrix, bilinear, and re-binarised at ``threshold`` (bool)."""
    h, w = arr.shape[1:]
    out = np.empty_like(arr)
    for i, m in enumerate(mats):
        cv2.warpAffine(arr[i], m, (w, h), dst=out[i], flags=cv2.INTER_LINEAR, borderValue=0.0)
    return out >= threshold


def rotate(
    maps: torch.Tensor, angle_deg: Union[float, torch.Tensor], threshold: float = ROTATE_THRESHOLD
) -> torch.Tensor:
    """Rotate maps ``(..., H, W)`` counter-clockwise by ``angle_deg`` about the map centre.

    ``angle_deg`` is a number or a tensor broadcastable to the leading dims (one angle per map).
    Each map is warped with ``cv2.warpAffine`` (bilinear) and re-binarised: a unit is on when its
    interpolated value is >= ``threshold`` (0.5: a point or line keeps about its area, as
    nearest-neighbour would, while bilinear sampling places it more evenly).
    """
    arr, shape = _flat_maps(maps)
    angles = torch.as_tensor(angle_deg, dtype=torch.float64).expand(shape[:-2]).reshape(-1)
    h, w = shape[-2:]
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    turns = {a: cv2.getRotationMatrix2D(c, a, 1.0) for a in set(angles.tolist())}  # one matrix per angle
    out = _warp_all(arr, [turns[a] for a in angles.tolist()], threshold)
    return torch.from_numpy(out).reshape(shape).to(maps.device, maps.dtype)  # 0/1 in the maps' dtype


def mirror(maps: torch.Tensor) -> torch.Tensor:
    """Left-right reflection of maps ``(..., H, W)`` about the vertical line through the centre."""
    return torch.flip(maps, dims=(-1,))


def principal_axis(mask: np.ndarray) -> tuple[float, float, float, float]:
    """(cx, cy, theta_deg, axis_ratio) of a 2-D array's on-pixels (weights = values).

    theta is the direction of the major axis, counter-clockwise from the image x axis as seen
    on screen; axis_ratio = sqrt(lambda_max / lambda_min) of the second-moment matrix (1 for an
    isotropic shape, larger the more elongated).
    """
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return float("nan"), float("nan"), float("nan"), float("nan")
    wts = mask[ys, xs].astype(np.float64)
    wts = wts / wts.sum()
    cx, cy = float((wts * xs).sum()), float((wts * ys).sum())
    dx, dy = xs - cx, -(ys - cy)  # y up, so angles read counter-clockwise on screen
    cov = np.array([[(wts * dx * dx).sum(), (wts * dx * dy).sum()],
                    [(wts * dx * dy).sum(), (wts * dy * dy).sum()]])
    evals, evecs = np.linalg.eigh(cov)
    vx, vy = evecs[:, 1]
    theta = float(np.degrees(np.arctan2(vy, vx)))
    ratio = float(np.sqrt(evals[1] / max(evals[0], 1e-12)))
    return cx, cy, theta, ratio


def flip_main_axis(maps: torch.Tensor, threshold: float = ROTATE_THRESHOLD) -> torch.Tensor:
    """Reflect each map ``(..., H, W)`` about its own principal axis (through its centroid).

    For a shape whose axis makes angle ``t`` with the x axis the reflection is
    ``p' = c + [[cos 2t, -sin 2t], [-sin 2t, -cos 2t]] (p - c)`` in image coordinates (y down);
    it is its own inverse, so it serves directly as the warp matrix.  Empty maps stay empty.
    """
    arr, shape = _flat_maps(maps)
    mats = []
    for a in arr:
        cx, cy, theta, _ = principal_axis(a)
        if np.isnan(cx):
            mats.append(np.float64([[1, 0, 0], [0, 1, 0]]))
            continue
        t = np.radians(theta)
        # reflection about direction (cos t, -sin t) in image coords (y down)
        r = np.array([[np.cos(2 * t), -np.sin(2 * t)], [-np.sin(2 * t), -np.cos(2 * t)]])
        c = np.array([cx, cy])
        mats.append(np.hstack([r, (c - r @ c)[:, None]]))
    out = _warp_all(arr, mats, threshold)
    return torch.from_numpy(out).reshape(shape).to(maps.device, maps.dtype)  # 0/1 in the maps' dtype


def iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Intersection over union of binary maps ``(..., H, W)``, one value per map (1 if both empty)."""
    a, b = a > 0.5, b > 0.5
    inter = (a & b).sum(dim=(-2, -1)).double()
    union = (a | b).sum(dim=(-2, -1)).double()
    return torch.where(union > 0, inter / union.clamp(min=1), torch.ones_like(union)).float()


_PLUS = torch.tensor([[0, 0], [-1, 0], [1, 0], [0, -1], [0, 1]])  # a dot: centre + 4 neighbours


def three_dot_images(
    n: int, generator: torch.Generator, size: int = 32, inner: int = 23
) -> torch.Tensor:
    """``n`` maps ``(n, size, size)`` with three random dots in the central ``inner x inner`` square.

    Dot centres are uniform over the inner square's pixels (thesis: 23x23 inside 32x32, so that
    most rotations keep the dots on the map); a dot is a 5-pixel plus, large enough to survive a
    bilinear ``rotate`` at any angle.  Dots may coincide.  Draws only from ``generator``.
    """
    return three_dot_maps(three_dot_centres(n, generator, size, inner), size)


def three_dot_centres(n: int, generator: torch.Generator, size: int = 32, inner: int = 23) -> torch.Tensor:
    """The dot centres ``(n, 3, 2)`` (x, y) of :func:`three_dot_images`, drawn from ``generator``."""
    if not (1 <= inner <= size - 2):
        raise ValueError(f"inner must lie in [1, size - 2], got inner={inner}, size={size}")
    lo = (size - inner) // 2
    return torch.randint(lo, lo + inner, (n, 3, 2), generator=generator)


def three_dot_maps(centres: torch.Tensor, size: int = 32, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """The three-dot maps ``(..., size, size)`` (0/1 in ``dtype``) of dot centres ``(..., 3, 2)``."""
    lead = centres.shape[:-2]
    c = centres.reshape(-1, 3, 2)
    n = c.shape[0]
    pts = (c[:, :, None, :] + _PLUS[None, None]).reshape(n, -1, 2).clamp(0, size - 1)
    out = torch.zeros(n, size, size, dtype=dtype)
    idx = torch.arange(n)[:, None].expand(-1, pts.shape[1])
    out[idx, pts[..., 1], pts[..., 0]] = 1
    return out.reshape(*lead, size, size)


def three_dot_pairs(
    n: int, angle_deg: Union[float, torch.Tensor], generator: torch.Generator,
    size: int = 32, inner: int = 23,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Forward-model training pairs: three-dot images and the same images rotated by ``angle_deg``."""
    x = three_dot_images(n, generator, size, inner)
    return x, rotate(x, angle_deg)
