"""Measured properties of stimulus shapes, and the design rules of the builtin sets.

The rules and their thresholds are written in docs/stimuli.md ("Design rules of the builtin
sets"); the constants below are the same numbers.  Per object:

* ``elongation``: ``sqrt(lambda_max / lambda_min)`` of the filled shape at 0 degrees (stored mask);
* ``axis_min`` / ``axis_max``: the same ratio on the 32x32 edge map (direct path), lowest and
  highest over the protocol's angles and appearances;
* ``corners``: vertices of the outer outline at 0 degrees (256 px, ``approxPolyDP``, 2 px);
* ``fill`` / ``sides``: area over the smallest enclosing rectangle, and its long / short side;
* ``mirror_iou``: best IoU of the mirror image with the original over rotations (1 degree
  steps); ``mirror_uncovered``: the part of the original the best-aligned mirror leaves uncovered;
* ``symmetry_iou``: best IoU of the shape with itself turned by 30 to 330 degrees;
* ``pieces``: 4-connected regions of the filled shape; ``edge_components``: the most 8-connected
  components of the edge map in any protocol view;
* ``distinct_iou``: best IoU with another object of the set or its mirror image (``nearest``);
* ``near_copy``: for cell shapes, the fewest cells added or removed to turn the object into
  another object of the set or its mirror image, at any quarter turn and shift (``near_copy_of``).

IoUs are taken between filled shapes scaled to the same area, centred on their centroids.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Optional

import cv2
import numpy as np

from neuroimagery.vision.edges import principal_axis
from neuroimagery.vision.shapes import CELL, Shape
from neuroimagery.vision.stimulus_sets import StimulusSet, get_stimulus_set, list_stimulus_sets

__all__ = [
    "ObjectMeasures", "Check", "SetReport", "measure_object_shapes", "measure_set", "check_rules",
    "kind_of", "training_set_of", "format_report", "near_copy_distance", "shape_cells", "KINDS",
]

# thresholds (docs/stimuli.md, "Design rules of the builtin sets")
ELONGATION_CLEAR = 3.0  # clear main axis: elongation >= this
AXIS_CLEAR = 2.1  # clear axis in the edge map: axis strength >= this in every view
MIRROR_MAJOR = 0.75  # mirrors differ in major parts: mirror IoU <= this
MORE_CORNERS = 2  # more features: corners >= the training set's most + this
AS_CLEAR = 0.9  # axis as clear: mean elongation >= this x the training set's mean
ELONGATION_WEAK = 1.2  # no strong axis: elongation <= this
AXIS_WEAK = 1.2  # no axis in the edge map: axis strength <= this in every view
SQUARE_FILL = 0.75  # square-like: fill >= this
SQUARE_SIDES = 1.2  # square-like: enclosing rectangle side ratio <= this
MIRROR_SMALL = 0.80  # mirrors differ in small details: mirror IoU >= this
CHIRAL = 0.95  # chiral: mirror IoU <= this
SYMMETRY = 0.95  # no rotational symmetry: symmetry IoU <= this
DISTINCT = 0.75  # distinct objects: distinctness <= this
NEAR_COPY = 2  # no near-copies: near-copy distance >= this (cell shapes)

KINDS = {
    "axis": "clear main axis (training set)",
    "features": "clear main axis, more features than the training set",
    "square": "square-like, no strong axis",
    "generic": "rules of every set",
}
_KIND = {"exp3-a": "axis", "exp4-A": "axis", "exp3-b": "features", "exp4-B": "features",
         "exp3-c": "square", "exp4-C": "square", "L": "generic"}
_TRAINING = {"exp3-b": "exp3-a", "exp4-B": "exp4-A"}
_VERSION = re.compile(r"-v\d+$")

_PAD = 2  # border that Shape adds around a mask
_AREA = 3000.0  # pixels of each filled shape in the IoU drawings
_STEP = 1  # degrees between the rotations compared
_SYMMETRY_FROM = 30  # rotations closer than this to 0 degrees are not a symmetry


def kind_of(name: str) -> str:
    """The kind of rules a builtin set meets (``generic`` for other sets)."""
    return _KIND.get(_VERSION.sub("", name), "generic")


def training_set_of(name: str) -> Optional[str]:
    """The training set a first-generalisation set is compared with (same version if it exists)."""
    base = _VERSION.sub("", name)
    if base not in _TRAINING:
        return None
    train = _TRAINING[base]
    version = name[len(base):]
    return train + version if version and train + version in list_stimulus_sets() else train


@dataclass
class ObjectMeasures:
    obj: str
    elongation: float
    axis_min: float
    axis_max: float
    corners: int
    fill: float
    sides: float
    mirror_iou: float
    mirror_uncovered: float
    symmetry_iou: float
    pieces: int
    edge_components: int
    distinct_iou: float = float("nan")
    nearest: str = ""
    near_copy: Optional[int] = None  # near-copy distance to the nearest other object (cell shapes)
    near_copy_of: str = ""


@dataclass
class Check:
    rule: str
    threshold: str
    values: list[tuple[str, str, bool]]  # (object or set, value, holds)

    @property
    def ok(self) -> bool:
        return all(v[2] for v in self.values)


@dataclass
class SetReport:
    name: str
    kind: str
    objects: list[ObjectMeasures]
    checks: list[Check] = field(default_factory=list)
    training: Optional[str] = None

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def broken(self) -> list[str]:
        return [c.rule for c in self.checks if not c.ok]


# ---------------------------------------------------------------------- drawings for IoUs
class _Drawing:
    """A shape scaled to ``_AREA`` pixels, drawn turned about its centroid on a square canvas."""

    def __init__(self, shape: Shape):
        self.shape = shape
        self.scale = float(np.sqrt(_AREA / shape.mask.sum()))
        self.radius = shape.radius * self.scale

    def draw(self, angle: float, mirror: bool, side: int) -> np.ndarray:
        src = self.shape.mask[:, ::-1] if mirror else self.shape.mask
        cx, cy = self.shape.centroid
        if mirror:
            cx = src.shape[1] - 1 - cx
        src = src.astype(np.float32)
        scale = self.scale
        if scale < 0.5:  # shrink by area averaging first so that bilinear sampling does not alias
            f = 2.0 * scale
            small = cv2.resize(src, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
            sx, sy = small.shape[1] / src.shape[1], small.shape[0] / src.shape[0]
            cx, cy, scale, src = (cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5, scale / f, small
        m = cv2.getRotationMatrix2D((cx, cy), float(angle), scale)
        c = (side - 1) / 2.0
        m[0, 2] += c - cx
        m[1, 2] += c - cy
        return cv2.warpAffine(src, m, (side, side), flags=cv2.INTER_LINEAR, borderValue=0.0) >= 0.5


def _best_iou(fixed: np.ndarray, turned: np.ndarray, angles: np.ndarray) -> tuple[float, float, int]:
    """Best IoU of ``fixed`` with ``turned[k]`` over ``angles``: (iou, uncovered part of turned, k)."""
    inter = (turned[angles] & fixed).sum(axis=(1, 2))
    union = (turned[angles] | fixed).sum(axis=(1, 2))
    v = inter / np.maximum(union, 1)
    k = int(np.argmax(v))
    area = turned[angles[k]].sum()
    return float(v[k]), float(1.0 - inter[k] / max(area, 1)), int(angles[k])


# ---------------------------------------------------------------------- measuring
def _largest_outline(mask: np.ndarray) -> np.ndarray:
    cnts, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return max(cnts, key=cv2.contourArea)


def _outline(shape: Shape) -> tuple[int, float, float]:
    """(corners, fill, sides): corners of the shape drawn 256 px wide at 0 degrees; fill and
    side ratio of the smallest enclosing rectangle of the stored mask."""
    drawn = shape.render(0.0, False, 256) > 0.5
    corners = len(cv2.approxPolyDP(_largest_outline(drawn), 2.0, True))
    (_, _), (w, h), _ = cv2.minAreaRect(_largest_outline(shape.mask))
    w, h = w + 1.0, h + 1.0  # from pixel centres to pixel edges
    return corners, float(shape.mask.sum() / (w * h)), float(max(w, h) / min(w, h))


def shape_cells(shape: Shape) -> Optional[np.ndarray]:
    """The cell grid (bool) of a shape drawn from a polyomino grid, or None for other shapes."""
    m = shape.mask[_PAD:-_PAD, _PAD:-_PAD]
    h, w = m.shape
    if h % CELL or w % CELL or shape.mask.shape != (h + 2 * _PAD, w + 2 * _PAD):
        return None
    cells = m[CELL // 2::CELL, CELL // 2::CELL].astype(bool)
    return cells if np.array_equal(np.kron(cells, np.ones((CELL, CELL), bool)), m > 0) else None


def near_copy_distance(a: np.ndarray, b: np.ndarray) -> int:
    """Fewest cells added or removed to turn cell grid ``a`` into ``b`` or its mirror image, at any
    quarter turn and shift."""
    a = a.astype(bool)
    best = int(a.sum() + b.sum())
    for flip in (False, True):
        bb = b[:, ::-1] if flip else b
        for k in range(4):
            r = np.rot90(bb, k).astype(bool)
            H, W = a.shape[0] + 2 * r.shape[0], a.shape[1] + 2 * r.shape[1]
            big = np.zeros((H, W), bool)
            big[r.shape[0]:r.shape[0] + a.shape[0], r.shape[1]:r.shape[1] + a.shape[1]] = a
            for y in range(H - r.shape[0] + 1):
                for x in range(W - r.shape[1] + 1):
                    win = big[y:y + r.shape[0], x:x + r.shape[1]]
                    outside = a.sum() - win.sum()
                    best = min(best, int((win ^ r).sum() + outside))
    return best


def measure_object_shapes(stimulus_set: StimulusSet, eye=None) -> list[ObjectMeasures]:
    """Every property of every object of ``stimulus_set`` (see the module docstring)."""
    from neuroimagery.vision import VisionConfig, make_eye

    eye = make_eye(VisionConfig(size=32)) if eye is None else eye
    objs = stimulus_set.objects
    shapes = {o: stimulus_set.shape(o) for o in objs}
    draws = {o: _Drawing(s) for o, s in shapes.items()}
    cells = {o: shape_cells(s) for o, s in shapes.items()}
    side = 2 * int(np.ceil(max(d.radius for d in draws.values()))) + 6
    angles = np.arange(0, 360, _STEP)
    turned = {o: np.stack([d.draw(a, False, side) for a in angles]) for o, d in draws.items()}
    mirrored = {o: d.draw(0.0, True, side) for o, d in draws.items()}
    everything = np.arange(len(angles))
    sym = everything[(angles >= _SYMMETRY_FROM) & (angles <= 360 - _SYMMETRY_FROM)]

    items = stimulus_set.items()
    maps = eye.edge_maps(stimulus_set, items, 32).numpy()
    out = []
    for o in objs:
        mine = [i for i, it in enumerate(items) if it[0] == o]
        ratios = [principal_axis(maps[i])[3] for i in mine]
        comps = [cv2.connectedComponents(maps[i].astype(np.uint8), connectivity=8)[0] - 1 for i in mine]
        corners, fill, sides = _outline(shapes[o])
        m_iou, m_unc, _ = _best_iou(mirrored[o], turned[o], everything)
        s_iou = _best_iou(turned[o][0], turned[o], sym)[0]
        pieces = cv2.connectedComponents(shapes[o].mask, connectivity=4)[0] - 1
        rec = ObjectMeasures(o, float(principal_axis(shapes[o].mask.astype(np.float64))[3]),
                             float(min(ratios)), float(max(ratios)), corners, fill, sides,
                             m_iou, m_unc, s_iou, int(pieces), int(max(comps)))
        best, nearest = -1.0, ""
        for p in objs:
            if p == o:
                continue
            for app, fixed in (("", turned[o][0]), (" mirror", mirrored[o])):
                # IoU(o, mirror of p turned) = IoU(mirror of o, p turned back): one set of drawings
                v = _best_iou(fixed, turned[p], everything)[0]
                if v > best:
                    best, nearest = v, p + app
        if nearest:
            rec.distinct_iou, rec.nearest = best, nearest
        mine_cells = cells[o]
        if mine_cells is not None and len(objs) > 1 and all(cells[p] is not None for p in objs):
            rec.near_copy, rec.near_copy_of = min(
                (near_copy_distance(mine_cells, cells[p]), p) for p in objs if p != o)
        out.append(rec)
    return out


# ---------------------------------------------------------------------- rules
def _per_object(rule, threshold, ms, value, holds) -> Check:
    return Check(rule, threshold, [(m.obj, value(m), bool(holds(m))) for m in ms])


def check_rules(kind: str, ms: list[ObjectMeasures],
                training: Optional[list[ObjectMeasures]] = None, pairs_are_mirrors: bool = False
                ) -> list[Check]:
    """The rules of ``kind`` (``axis``, ``features``, ``square``, ``generic``) on measured objects.

    ``training``: the measures of the training set a ``features`` set is compared with.
    ``pairs_are_mirrors``: the objects are each other's mirror images by design (set ``L``), so
    the distinctness rule does not apply.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind of rules {kind!r}; kinds: {', '.join(KINDS)}")
    checks = []
    if kind in ("axis", "features"):
        checks += _axis_rules(ms)
    if kind == "features":
        checks += _features_rules(ms, training)
    if kind == "square":
        checks += _square_rules(ms)
    return checks + _shared_rules(ms, pairs_are_mirrors)


def _f2(x) -> str:
    return f"{x:.2f}"


def _axis_rules(ms: list[ObjectMeasures]) -> list[Check]:
    return [
        _per_object("clear main axis", f"elongation >= {ELONGATION_CLEAR}", ms,
                    lambda m: _f2(m.elongation), lambda m: m.elongation >= ELONGATION_CLEAR),
        _per_object("clear axis in the edge map", f"axis strength >= {AXIS_CLEAR} in every view",
                    ms, lambda m: _f2(m.axis_min), lambda m: m.axis_min >= AXIS_CLEAR),
        _per_object("mirrors differ in major parts", f"mirror IoU <= {MIRROR_MAJOR}", ms,
                    lambda m: _f2(m.mirror_iou), lambda m: m.mirror_iou <= MIRROR_MAJOR),
    ]


def _features_rules(ms: list[ObjectMeasures], training: Optional[list[ObjectMeasures]]) -> list[Check]:
    if not training:
        raise ValueError("the features rules need the training set's measures")
    most = max(t.corners for t in training)
    mean, ref = np.mean([m.elongation for m in ms]), np.mean([t.elongation for t in training])
    return [_per_object("more features", f"corners >= {most} + {MORE_CORNERS}", ms,
                        lambda m: str(m.corners), lambda m: m.corners >= most + MORE_CORNERS),
            Check("axis as clear as the training set's", f"mean elongation >= {AS_CLEAR} x {ref:.2f}",
                  [("mean", _f2(mean), bool(mean >= AS_CLEAR * ref))])]


def _square_rules(ms: list[ObjectMeasures]) -> list[Check]:
    return [
        _per_object("no strong axis", f"elongation <= {ELONGATION_WEAK}", ms,
                    lambda m: _f2(m.elongation), lambda m: m.elongation <= ELONGATION_WEAK),
        _per_object("no axis in the edge map", f"axis strength <= {AXIS_WEAK} in every view",
                    ms, lambda m: _f2(m.axis_max), lambda m: m.axis_max <= AXIS_WEAK),
        _per_object("square-like", f"fill >= {SQUARE_FILL}, sides <= {SQUARE_SIDES}", ms,
                    lambda m: f"{m.fill:.2f}/{m.sides:.2f}",
                    lambda m: m.fill >= SQUARE_FILL and m.sides <= SQUARE_SIDES),
        _per_object("mirrors differ in small details", f"mirror IoU >= {MIRROR_SMALL}", ms,
                    lambda m: _f2(m.mirror_iou), lambda m: m.mirror_iou >= MIRROR_SMALL),
    ]


def _shared_rules(ms: list[ObjectMeasures], pairs_are_mirrors: bool) -> list[Check]:
    """The rules of every kind: chiral, asymmetric, one piece, connected edges, distinct objects."""
    checks = [
        _per_object("chiral", f"mirror IoU <= {CHIRAL}", ms, lambda m: _f2(m.mirror_iou),
                    lambda m: m.mirror_iou <= CHIRAL),
        _per_object("no rotational symmetry", f"symmetry IoU <= {SYMMETRY}", ms,
                    lambda m: _f2(m.symmetry_iou), lambda m: m.symmetry_iou <= SYMMETRY),
        _per_object("one piece", "one 4-connected region", ms, lambda m: str(m.pieces),
                    lambda m: m.pieces == 1),
        _per_object("edge map connected", "one 8-connected component in every view", ms,
                    lambda m: str(m.edge_components), lambda m: m.edge_components == 1),
    ]
    if not pairs_are_mirrors and len(ms) > 1:
        checks.append(_per_object("distinct objects", f"distinctness <= {DISTINCT}", ms,
                                  lambda m: f"{m.distinct_iou:.2f} ({m.nearest})",
                                  lambda m: m.distinct_iou <= DISTINCT))
        if all(m.near_copy is not None for m in ms):
            checks.append(_per_object("no near-copies", f"near-copy distance >= {NEAR_COPY}", ms,
                                      lambda m: f"{m.near_copy} ({m.near_copy_of})",
                                      lambda m: m.near_copy >= NEAR_COPY))
    return checks


def measure_set(name_or_path: str, like: Optional[str] = None, eye=None) -> SetReport:
    """Measure a builtin set or a folder and check the rules of its kind.

    like: a builtin set whose rules (and protocol views) a folder is checked against; by default
    a builtin set gets its own rules and a folder the rules of every set.
    """
    stim = get_stimulus_set(name_or_path)
    ref = like if like is not None else (name_or_path if name_or_path in list_stimulus_sets() else None)
    if like is not None:
        base = get_stimulus_set(like)
        stim = stim.with_protocol(base.angles, base.appearances, base.protocol, base.rotated_side,
                                  base.radius_fraction)
    kind = kind_of(ref) if ref is not None else "generic"
    ms = measure_object_shapes(stim, eye)
    train_name = training_set_of(ref) if ref is not None else None
    training = measure_object_shapes(get_stimulus_set(train_name), eye) if train_name else None
    mirrors = stim.protocol == "reference"
    if mirrors:  # the objects are each other's mirror images by design: no distinctness
        for m in ms:
            m.distinct_iou, m.nearest, m.near_copy, m.near_copy_of = float("nan"), "", None, ""
    return SetReport(stim.name, kind, ms, check_rules(kind, ms, training, mirrors), train_name)


# ---------------------------------------------------------------------- printing
_COLUMNS = [("object", "obj", "{}"), ("elong.", "elongation", "{:.2f}"),
            ("axis min", "axis_min", "{:.2f}"), ("axis max", "axis_max", "{:.2f}"),
            ("corners", "corners", "{}"), ("fill", "fill", "{:.2f}"), ("sides", "sides", "{:.2f}"),
            ("mirror IoU", "mirror_iou", "{:.2f}"), ("mirror uncov.", "mirror_uncovered", "{:.0%}"),
            ("symmetry", "symmetry_iou", "{:.2f}"), ("pieces", "pieces", "{}"),
            ("edge comp.", "edge_components", "{}"), ("distinct", "distinct_iou", "{:.2f}"),
            ("nearest", "nearest", "{}"), ("near-copy", "near_copy", "{}"),
            ("of", "near_copy_of", "{}")]


def _row(m: ObjectMeasures) -> list[str]:
    out = []
    for _, attr, fmt in _COLUMNS:
        v = getattr(m, attr)
        missing = v is None or (isinstance(v, float) and np.isnan(v))
        out.append("-" if missing else fmt.format(v))
    return out


def format_report(report: SetReport, markdown: bool = False) -> str:
    """The properties (one row per object) and, per rule, its values and whether it holds."""
    head = [c[0] for c in _COLUMNS]
    rows = [_row(m) for m in report.objects]
    title = f"{report.name}: {KINDS[report.kind]}"
    if report.training:
        title += f" (compared with {report.training})"
    lines = [title]
    if markdown:
        lines += ["", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines += [""]
    else:
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
        for r in [head] + rows:
            lines.append("  " + "  ".join(v.rjust(w) for v, w in zip(r, widths)))
    for c in report.checks:
        vals = ", ".join(f"{o} {v}" + ("" if ok else " (breaks)") for o, v, ok in c.values)
        mark = "ok  " if c.ok else "FAIL"
        lines.append(("- " if markdown else "  ") + f"{mark} {c.rule} ({c.threshold}): {vals}")
    n = len(report.broken)
    lines.append(("" if markdown else "  ")
                 + ("every rule holds" if n == 0 else f"{n} rule(s) broken: {', '.join(report.broken)}"))
    return "\n".join(lines)
