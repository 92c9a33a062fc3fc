"""Contact sheets and measures of stimulus sets: ``python -m neuroimagery.app.stimuli SET --out DIR``.

Each row is one object in one appearance, each column one protocol angle; every cell shows the
drawn stimulus beside its 32x32 edge map (direct path).  ``--list`` prints the builtin set names;
a folder path in place of SET makes a set from the folder's images.  ``--measure [SET ...]``
prints the measured properties of every object and whether each design rule holds
(docs/stimuli.md), for every builtin set by default; ``--like SET`` checks folders against the
rules of a builtin set.  Errors in the user's input print one line on stderr and exit with
status 2.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from neuroimagery.core.arguments import ToolParser, check, check_size, count, path as nonempty_path, run_tool
from neuroimagery.core.errors import UserInputError

__all__ = ["contact_sheet", "main"]

_CELL = 96  # pixels per stimulus thumbnail and per edge-map thumbnail
_LABEL_W = 150
_HEAD_H = 28


def contact_sheet(stimulus_set, size: int = 32) -> np.ndarray:
    """BGR image: every object x appearance (rows) x angle (columns), stimulus beside edge map."""
    from neuroimagery.vision import VisionConfig, make_eye

    eye = make_eye(VisionConfig(size=size))
    rows = [(o, ap) for o in stimulus_set.objects for ap in stimulus_set.appearances]
    items = [(o, a, ap) for o, ap in rows for a in stimulus_set.angles]
    maps = eye.edge_maps(stimulus_set, items, size).numpy()
    n_cols = len(stimulus_set.angles)
    col_w = 2 * _CELL + 8
    sheet = np.full((_HEAD_H + len(rows) * (_CELL + 8), _LABEL_W + n_cols * col_w, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for j, a in enumerate(stimulus_set.angles):
        cv2.putText(sheet, f"{a:g} deg", (_LABEL_W + j * col_w + 60, 20), font, 0.5, (0, 0, 0), 1,
                    cv2.LINE_AA)
    k = 0
    for i, (o, ap) in enumerate(rows):
        y = _HEAD_H + i * (_CELL + 8)
        cv2.putText(sheet, f"{o} {ap}", (6, y + _CELL // 2), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for j, a in enumerate(stimulus_set.angles):
            x = _LABEL_W + j * col_w
            img = cv2.resize(stimulus_set.image(o, a, ap), (_CELL, _CELL), interpolation=cv2.INTER_AREA)
            edge = cv2.resize((maps[k] * 255).astype(np.uint8), (_CELL, _CELL),
                              interpolation=cv2.INTER_NEAREST)
            sheet[y:y + _CELL, x:x + _CELL] = img
            sheet[y:y + _CELL, x + _CELL + 2:x + 2 * _CELL + 2] = edge[..., None]
            k += 1
    return sheet


MAX_SIZE = 1024  # the side of an edge map without --allow-large (the sheet grows with its square)


def _parser() -> ToolParser:
    ap = ToolParser(
        prog="python -m neuroimagery.app.stimuli",
        description="Write a contact sheet (PNG) of a stimulus set: every object, angle and "
                    "appearance beside its edge map.")
    ap.add_argument("set", nargs="*", type=nonempty_path, help="a builtin set name (see --list) or a folder of images; "
                                           "with --measure, any number (default: every builtin set)")
    ap.add_argument("--out", type=nonempty_path, default=".", help="folder for <set>.png (default: current folder)")
    ap.add_argument("--list", action="store_true", help="print the builtin set names and exit")
    ap.add_argument("--size", type=count, default=32, help="side of the edge map (default 32)")
    ap.add_argument("--allow-large", action="store_true", help=f"allow --size above {MAX_SIZE}")
    ap.add_argument("--measure", action="store_true",
                    help="print each object's measured properties and whether each design rule holds")
    ap.add_argument("--like", metavar="SET", help="with --measure: check folders against the rules "
                                                  "(and views) of this builtin set")
    ap.add_argument("--markdown", action="store_true", help="with --measure: markdown tables")
    return ap


def _measure(args) -> int:
    from neuroimagery.vision import list_stimulus_sets
    from neuroimagery.vision.measure import format_report, measure_set

    if args.like is not None and args.like not in list_stimulus_sets():
        raise UserInputError(f"--like {args.like!r} is not a builtin set; sets: "
                             f"{', '.join(list_stimulus_sets())}")
    names = args.set or list_stimulus_sets()
    reports = []
    for name in names:
        like = args.like if args.like is not None and os.path.isdir(name) else None
        reports.append(format_report(measure_set(name, like), args.markdown))
    print("\n\n".join(reports))
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    return run_tool(_main, argv)


def _main(argv: Optional[Sequence[str]]) -> int:
    args = _parser().parse_args(argv)
    from neuroimagery.vision import get_stimulus_set, list_stimulus_sets

    check("--size", args.size, ge=8)
    check_size("--size", args.size, MAX_SIZE, args.allow_large)
    if args.like is not None and not args.measure:
        raise UserInputError("--like has no effect without --measure")
    if args.markdown and not args.measure:
        raise UserInputError("--markdown has no effect without --measure")

    if args.list:
        print("\n".join(list_stimulus_sets()))
        return 0
    if args.measure:
        return _measure(args)
    if len(args.set) != 1:
        raise UserInputError("name one stimulus set or folder (see --list)")
    args.set = args.set[0]
    stim = get_stimulus_set(args.set)
    sheet = contact_sheet(stim, args.size)
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"cannot create output folder {out}: {exc.strerror}") from None
    name = stim.name if not os.path.isdir(args.set) else Path(args.set).resolve().name
    path = out / f"{name}.png"
    if not cv2.imwrite(str(path), sheet):
        raise UserInputError(f"cannot write {path}")
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
