"""Vision measurements and timings: ``python benchmarks/bench_vision.py [--camera-pairs N]``.

Prints (markdown) the principal-axis ratio of every builtin object, the rotate-vs-redraw IoU of
edge maps, the camera-vs-direct IoU, and the time per image of each path.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from neuroimagery.vision import (
    VisionConfig,
    get_stimulus_set,
    iou,
    list_stimulus_sets,
    make_eye,
    rotate,
    shape_elongation,
)

def _step(name: str) -> float:
    """The protocol's angle step: 15 (set L), 45 (Exp. 3 sets), 30 (Exp. 4 sets)."""
    return 15.0 if name == "L" else 45.0 if name.startswith("exp3") else 30.0


def elongations() -> None:
    print("| set | object | axis ratio |\n|---|---|---|")
    for name in list_stimulus_sets():
        s = get_stimulus_set(name)
        for o in s.objects:
            print(f"| {name} | {o} | {shape_elongation(s, o):.2f} |")


def rotate_vs_redraw(eye) -> None:
    print("\n| set | step (deg) | IoU mean | IoU min | one-unit shift IoU |\n|---|---|---|---|---|")
    for name in list_stimulus_sets():
        s = get_stimulus_set(name)
        step = _step(name)
        app = s.appearances[0]
        a0 = np.arange(-90.0, 90.0, step)
        e0 = eye.edge_maps(s, [(o, a, app) for o in s.objects for a in a0])
        e1 = eye.edge_maps(s, [(o, a + step, app) for o in s.objects for a in a0])
        v = iou(rotate(e0, step), e1)
        sh = iou(torch.roll(e1, 1, dims=-1), e1)
        print(f"| {name} | {step:g} | {v.mean():.3f} | {v.min():.3f} | {sh.mean():.3f} |")


def camera_vs_direct(eye, n_pairs: int) -> None:
    cam = make_eye(VisionConfig(kind="camera"))
    print("\n| set | views | IoU target | IoU rotated | camera s/pair |\n|---|---|---|---|---|")
    try:
        for name in ("exp3-a", "exp3-c", "exp4-B", "exp4-C"):
            s = get_stimulus_set(name)
            pairs = [p for o in s.objects for p in s.pairs(o)]
            idx = np.random.default_rng(0).choice(len(pairs), n_pairs, replace=False)
            pairs = [pairs[i] for i in sorted(idx)]
            cam.scene(s)
            t = time.perf_counter()
            ct, cr = cam.pair_edge_maps(s, pairs)
            dt = (time.perf_counter() - t) / len(pairs)
            it, ir = eye.pair_edge_maps(s, pairs)
            print(f"| {name} | {2 * len(pairs)} | {iou(ct, it).mean():.3f} | "
                  f"{iou(cr, ir).mean():.3f} | {dt:.3f} |")
    finally:
        cam.close()


def direct_timing(eye) -> None:
    s = get_stimulus_set("exp4-A")
    pairs = [p for o in s.objects for p in s.pairs(o)]
    t = time.perf_counter()
    eye.pair_edge_maps(s, pairs)
    dt = time.perf_counter() - t
    print(f"\ndirect path: {len(pairs)} pairs in {dt:.2f} s ({1e3 * dt / len(pairs):.1f} ms/pair)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--camera-pairs", type=int, default=24, help="pairs per set for the camera")
    args = ap.parse_args()
    eye = make_eye(VisionConfig())
    elongations()
    rotate_vs_redraw(eye)
    direct_timing(eye)
    if args.camera_pairs > 0:
        camera_vs_direct(eye, args.camera_pairs)


if __name__ == "__main__":
    main()
