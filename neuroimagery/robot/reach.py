"""The reachable area of the tool-use world: where the iCub's free (left) hand can grab the toy.

The rake is in the right hand, so the left hand is the one that grabs the toy once it is in reach.
The area is the set of table points, at the height of the toy's centre, where the left palm (the
origin of the URDF's ``l_hand`` frame) can be with the torso and left-arm joints inside their URDF
limits. Its far edge, one x per band of y (the *frontier*), is computed by forward kinematics of
the chain ``root_link -> l_hand``: random joint vectors drawn inside the limits, the palm positions
within ``height_band`` of the toy centre's height kept, the farthest x of each y band, then a
hill climb from the best vector of each band (random steps inside the limits that keep the palm in
its band and push it farther). The result is stored in :data:`neuroimagery.robot.config.REACH_FRONTIER`
(``python -m neuroimagery.robot.reach`` recomputes and prints it).
"""
from __future__ import annotations

import numpy as np
import torch

from ..core.arguments import ToolParser, check, check_size, count, run_tool, seed
from .kinematics import ICUB_MODEL, icub_urdf_text, world_T_root

LEFT_CHAIN = ("torso_pitch", "torso_roll", "torso_yaw", "l_shoulder_pitch", "l_shoulder_roll", "l_shoulder_yaw",
              "l_elbow", "l_wrist_prosup", "l_wrist_pitch", "l_wrist_yaw")


def left_palm_chain(dtype=torch.float64):
    """pytorch-kinematics chain ``root_link -> l_hand`` and its joint limits (J, 2)."""
    import pytorch_kinematics as pk

    chain = pk.build_serial_chain_from_urdf(icub_urdf_text(ICUB_MODEL, keep_geometry=False), end_link_name="l_hand",
                                            root_link_name="root_link").to(dtype=dtype)
    if tuple(chain.get_joint_parameter_names()) != LEFT_CHAIN:
        raise RuntimeError(f"unexpected left-arm chain {chain.get_joint_parameter_names()}")
    lo, hi = chain.get_joint_limits()
    return chain, torch.tensor([lo, hi], dtype=dtype).T.contiguous()


def palm_positions(chain, q: torch.Tensor, root_height: float) -> torch.Tensor:
    """World positions (N, 3) of the left palm for joint vectors ``q`` (N, J)."""
    T = world_T_root(root_height).to(q.dtype) @ chain.forward_kinematics(q).get_matrix()
    return T[:, :3, 3]


def compute_frontier(root_height: float, height: float, ys: np.ndarray, band_y: float = 0.01,
                     height_band: float = 0.01, samples: int = 400_000, climb_steps: int = 300, seed: int = 0
                     ) -> np.ndarray:
    """Farthest x (m) the left palm reaches at ``height`` (+- ``height_band``) in each band
    ``y +- band_y`` of ``ys``; NaN where it reaches none. Deterministic for a seed."""
    chain, lim = left_palm_chain()
    lo, hi = lim[:, 0], lim[:, 1]
    g = torch.Generator().manual_seed(seed)
    ys_t = torch.as_tensor(ys, dtype=torch.float64)
    best_x = torch.full((len(ys),), float("nan"), dtype=torch.float64)
    best_q = torch.zeros(len(ys), len(lo), dtype=torch.float64)
    for start in range(0, samples, 50_000):
        q = lo + (hi - lo) * torch.rand(min(50_000, samples - start), len(lo), generator=g, dtype=torch.float64)
        p = palm_positions(chain, q, root_height)
        ok_z = (p[:, 2] - height).abs() < height_band
        for b, y in enumerate(ys_t):
            m = ok_z & ((p[:, 1] - y).abs() < band_y)
            if bool(m.any()):
                i = torch.nonzero(m).flatten()[p[m, 0].argmax()]
                if not float(p[i, 0]) <= float(best_x[b]):  # NaN-safe: first hit or farther
                    best_x[b], best_q[b] = p[i, 0], q[i]
    found = ~torch.isnan(best_x)
    k = 32  # candidates per band in the hill climb
    step = 0.05 * (hi - lo)
    for _ in range(climb_steps):
        cand = best_q[:, None] + step * torch.randn(len(ys), k, len(lo), generator=g, dtype=torch.float64)
        cand = torch.maximum(torch.minimum(cand, hi), lo)
        p = palm_positions(chain, cand.reshape(-1, len(lo)), root_height).reshape(len(ys), k, 3)
        ok = ((p[..., 2] - height).abs() < height_band) & ((p[..., 1] - ys_t[:, None]).abs() < band_y)
        x = torch.where(ok, p[..., 0], torch.full_like(p[..., 0], -np.inf))
        xb, ib = x.max(1)
        better = found & (xb > best_x)
        best_x = torch.where(better, xb, best_x)
        best_q[better] = cand[better, ib[better]]
    return best_x.numpy()


MAX_SAMPLES = 10_000_000  # random joint vectors without --allow-large (memory grows with them)


def main(argv: list[str] | None = None) -> int:
    return run_tool(_main, argv)


def _main(argv: list[str] | None) -> int:
    from .config import REACH_YS, WorldConfig

    parser = ToolParser(prog="python -m neuroimagery.robot.reach", description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=count, default=400_000, help="random joint vectors")
    parser.add_argument("--seed", type=seed, default=0)
    parser.add_argument("--allow-large", action="store_true", help=f"allow more than {MAX_SAMPLES} samples")
    args = parser.parse_args(argv)
    check("--samples", args.samples, ge=1)
    check_size("--samples", args.samples, MAX_SAMPLES, args.allow_large)
    cfg = WorldConfig()
    xs = compute_frontier(cfg.root_height, cfg.table_top + cfg.toy_size / 2, np.array(REACH_YS), samples=args.samples,
                          seed=args.seed)
    print("REACH_FRONTIER = (" + ", ".join("None" if np.isnan(x) else f"{x:.3f}" for x in xs) + ")")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
