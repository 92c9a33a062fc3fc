"""Shapes of the stimulus sets: polyomino outlines drawn at any angle, plain or mirrored.

The thesis's stimulus figures (5.3, 6.1, 6.6) are not in its text, so the builtin shapes are
designed here from its descriptions: flat red outlines made of unit squares, like the
Hochberg & Gellman (1977) figures, each one chiral (its mirror image is not a rotation of it)
and without rotational symmetry, so that angle and appearance are always recoverable.

A :class:`Shape` holds a high-resolution binary mask.  It is drawn by one affine warp that
rotates it counter-clockwise about its centroid and scales it so that its farthest point from
the centroid lies at ``radius_fraction`` of the canvas side (``RADIUS_FRACTION`` unless a set
says otherwise): every shape fits its canvas (and the 32x32 map) at every angle.  The sets of
Experiments 3 and 4 use ``CH6_RADIUS_FRACTION``, by rule R5 of docs/choices.md the scale the other
sets follow (0.375 before, a scale fixed after its effect had been seen).
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "RADIUS_FRACTION",
    "CH6_RADIUS_FRACTION",
    "CANVAS",
    "RED_BGR",
    "BACKGROUND_BGR",
    "Shape",
    "grid_mask",
    "BUILTIN_GRIDS",
]

CANVAS = 128  # default side in pixels of a one-object image
RADIUS_FRACTION = 0.40  # farthest shape point from its centroid, as a fraction of the side
# Exp. 3-4 sets: the rule the other sets follow (docs/choices.md, R5)
CH6_RADIUS_FRACTION = RADIUS_FRACTION
RED_BGR = (40, 40, 210)  # shape colour (BGR)
BACKGROUND_BGR = (225, 225, 225)  # light grey background (BGR)
CELL = 48  # pixels per polyomino cell in the stored mask
_MIN_WORK = 384  # shapes are warped at >= this resolution, then area-averaged to the canvas


def grid_mask(grid: str, cell: int = CELL) -> np.ndarray:
    """Binary mask (uint8 0/1) of a polyomino written row by row, rows separated by '/'.

    '#' is a filled cell, '.' an empty one; the first row is the top of the shape.
    """
    rows = grid.strip().split("/")
    if len({len(r) for r in rows}) != 1 or set("".join(rows)) - set("#."):
        raise ValueError(f"bad polyomino grid {grid!r}")
    cells = np.array([[ch == "#" for ch in r] for r in rows], np.uint8)
    return np.kron(cells, np.ones((cell, cell), np.uint8))


class Shape:
    """A flat shape given by a binary mask; drawn rotated, mirrored, on a square canvas."""

    def __init__(self, mask: np.ndarray, name: str = ""):
        mask = (np.asarray(mask) > 0).astype(np.uint8)
        if mask.ndim != 2 or not mask.any():
            raise ValueError(f"shape {name!r}: mask must be a non-empty 2-D array")
        ys, xs = np.nonzero(mask)
        pad = 2
        self.mask = np.pad(mask[ys.min():ys.max() + 1, xs.min():xs.max() + 1], pad)
        self.name = name
        ys, xs = np.nonzero(self.mask)
        self.centroid = (float(xs.mean()), float(ys.mean()))
        # farthest pixel corner from the centroid
        dx = np.abs(xs - self.centroid[0]) + 0.5
        dy = np.abs(ys - self.centroid[1]) + 0.5
        self.radius = float(np.sqrt(dx * dx + dy * dy).max())

    def mirrored(self, name: str = "") -> "Shape":
        """The left-right mirror image."""
        return Shape(self.mask[:, ::-1], name or self.name + "-mirror")

    def render(self, angle_deg: float, mirror: bool = False, canvas: int = CANVAS,
               radius_fraction: float = RADIUS_FRACTION) -> np.ndarray:
        """Coverage (float32 in [0, 1], ``canvas x canvas``) of the shape turned by ``angle_deg``.

        Positive angles turn counter-clockwise on screen.  ``mirror`` reflects the shape left-right
        before turning it.  The farthest point lies ``radius_fraction`` of the side from the
        centre.  Drawn at a resolution >= ``_MIN_WORK`` and area-averaged, so edges are
        anti-aliased.
        """
        import cv2  # here: the names of the builtin sets (BUILTIN_GRIDS) are read without OpenCV

        if not 0.0 < radius_fraction <= 0.5:
            raise ValueError(f"radius_fraction must lie in (0, 0.5], got {radius_fraction}")
        ss = max(1, int(np.ceil(_MIN_WORK / canvas)))
        work = canvas * ss
        src = self.mask[:, ::-1] if mirror else self.mask
        cx, cy = self.centroid
        if mirror:
            cx = src.shape[1] - 1 - cx
        scale = radius_fraction * work / self.radius
        m = cv2.getRotationMatrix2D((cx, cy), float(angle_deg), scale)
        c_out = (work - 1) / 2.0
        m[0, 2] += c_out - cx
        m[1, 2] += c_out - cy
        src_f = src.astype(np.float32)
        if scale < 0.5:  # shrink first so bilinear sampling does not alias
            f = 2.0 * scale
            small = cv2.resize(src_f, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
            sx, sy = small.shape[1] / src.shape[1], small.shape[0] / src.shape[0]
            cxs, cys = (cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5
            m = cv2.getRotationMatrix2D((cxs, cys), float(angle_deg), scale / f)
            m[0, 2] += c_out - cxs
            m[1, 2] += c_out - cys
            src_f = small
        cov = cv2.warpAffine(src_f, m, (work, work), flags=cv2.INTER_LINEAR, borderValue=0.0)
        if ss > 1:
            cov = cv2.resize(cov, (canvas, canvas), interpolation=cv2.INTER_AREA)
        return np.clip(cov, 0.0, 1.0)


def colourise(coverage: np.ndarray) -> np.ndarray:
    """A red-on-light-grey BGR uint8 image from a coverage map in [0, 1]."""
    c = coverage[..., None]
    img = (1.0 - c) * np.float32(BACKGROUND_BGR) + c * np.float32(RED_BGR)
    return np.round(img).astype(np.uint8)


# Polyomino designs, rows top to bottom, '#' = cell.  Each set: 3 objects, except "L".  They meet
# the design rules of docs/stimuli.md (checked by tests/test_stimuli.py; measured by
# ``python -m neuroimagery.app.stimuli --measure``).
BUILTIN_GRIDS: dict[str, dict[str, str]] = {
    # Exp. 1-2: an upside-down L (a stem with a bar on top); object B is its mirror image.
    "L": {"A": "###/#../#../#../#.."},
    # Exp. 3 set a (training, Recog): five-cell bars with one feature -> clear main axis.
    "exp3-a": {"a1": "##/#./#./#./#.", "a2": "#./##/#./#./#.", "a3": ".#/##/#./#./#."},
    # Exp. 3 set b (Gen-I): six- and seven-cell bars, one cell wide, with three one-cell side
    # features each ("unseen and consist of many details", thesis 6.1.3) -> still a clear main axis.
    "exp3-b": {"b1": ".#./##./.#./.##/.#./.##", "b2": "##./.#./.#./.##/.#./##./.#.",
               "b3": ".#./.##/.#./.#./.##/##./.#."},
    # Exp. 3 set c (Gen-II): 5x5 squares with notches cut from the border: square-like, no axis,
    # and the mirror image differs from the original only in where the notches are.
    "exp3-c": {"c1": "..##./#####/#####/#####/.###.", "c2": "#...#/#####/.####/.####/#####",
               "c3": "#..##/####./#####/#####/#..##"},
    # Exp. 4 set A (training, Recog): six- and seven-cell bars with one feature -> clear main axis
    # (A1 a foot at one end, A2 a one-cell step, A3 a side nub).
    "exp4-A": {"A1": "##/#./#./#./#./#.", "A2": ".#/.#/##/#./#./#.", "A3": "#./#./##/#./#./#./#."},
    # Exp. 4 set B (Gen1): eight-cell bars with three one-cell side features each -> more features
    # than set A, and a main axis as clear as set A's.
    "exp4-B": {"B1": ".#./##./.#./.##/.#./.#./.##/.#.", "B2": ".##/.#./.#./.#./##./.#./##./.#.",
               "B3": ".#./.#./##./.#./.#./.##/.#./##."},
    # Exp. 4 set C (Gen2): 5x5 squares with notches cut from the border, like set c.
    "exp4-C": {"C1": "#...#/#####/.####/#####/#####", "C2": "..##./#####/#####/#####/..###",
               "C3": "#..##/#####/#####/.###./##.##"},
}

# The earlier designs of the sets changed to meet the design rules, kept so that results obtained
# with them can be reproduced (docs/stimuli.md lists the rules each one breaks).
BUILTIN_GRIDS.update({
    "exp3-b-v1": {"b1": ".#./##./.#./.##/.#./.##", "b2": ".#./.##/##./.#./.#./##.", "b3": "##./.#./.##/.#./##./.#."},
    "exp3-c-v1": {"c1": "##.#/.###/##../..#.", "c2": "####/.#.#/.#.#/.#..", "c3": "###./####/.#../.#.."},
    "exp4-A-v1": {"A1": "##/#./#./#./#./#.", "A2": ".#/.#/##/#./#./#.", "A3": "#./##/.#/.#/.#"},
    "exp4-B-v1": {"B1": "#../##./.#./.##/.#./##.", "B2": ".#./##./.#./.##/.#./.#.",
                  "B3": ".#./.##/##./.#./.##/.#."},
    "exp4-C-v1": {"C1": "##.#/.###/####/.##.", "C2": "####/##.#/.#.#/##.#", "C3": ".##./####/###./.###"},
})
