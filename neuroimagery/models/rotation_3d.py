"""Experiment 6 model: the Experiment 4 network (thesis 6.2, Fig. 6.7) carried into three dimensions.

Maps, batched over participants ``P`` and trials (flat rows): POCi / POCp and the per-move
candidates (``G^3`` voxel maps), PFCt / PFCft (target and its reflection), PFCtm / PFCfm (their
overlap with POCp), PPCp_a / PPCt_a (wrist posture per axis a = x, y, z), PPCc_a (gain fields,
eq. 6.9), PMCm (7 moves: still, -step/+step about x, y, z; eq. 6.10-6.11), PMCd (leaky competing
accumulator, eq. 6.12-6.13).

Connections: the forward models FM_m (:class:`~neuroimagery.nn.local.LocalConnection`, delta rule
eq. 6.4), C16_a / C17_a (supervised Kohonen SOMs, eq. 6.14-6.16), C20 hard-wired (PPCc -> PMCm),
C10 hard-wired (principal-plane reflection of the target map), the rest fixed relays.
"""
from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from ..nn import Delta, HardWired, LeakyCompetingAccumulator, PopulationMap, SOM
from ..nn.functional import gain_field, softmax_select
from ..nn.local import LocalConnection, offset_count
from . import voxels
from .rotation_embodied import check_proprioception, lca_gain  # the same evidence scale and wrist conditions as Exp 4

AXES = ("x", "y", "z")
WRIST_AXIS = "z"  # the line of sight: the axis the wrist turns the held object about (as in Exp 4)
MOVES = ("still",) + tuple(f"{a}{s}" for a in AXES for s in ("-", "+"))  # PMCm units


def move_angles(step: float) -> list[tuple[str | None, float]]:
    """(axis, degrees) of every PMCm unit, in :data:`MOVES` order."""
    return [(None, 0.0)] + [(a, s * step) for a in AXES for s in (-1.0, 1.0)]


def receptive_radius(side: int, step_deg: float) -> int:
    """Radius covering the largest displacement of one step inside the dot ball of radius G/2 - 1.5."""
    r = side / 2.0 - 1.5
    return int(math.ceil(2.0 * r * math.sin(math.radians(step_deg) / 2.0) - 1e-9))


def fm_bytes(side: int, step_deg: float, moves: int = len(MOVES)) -> int:
    """Bytes of the forward models of one participant (float32)."""
    return moves * side ** 3 * offset_count(receptive_radius(side, step_deg)) * 4


def grid_for_budget(budget_mb: float, step_deg: float, moves: int = len(MOVES)) -> int:
    """The largest even grid side in [8, 64] whose forward models fit ``budget_mb`` per participant."""
    best = None
    for g in range(8, 65, 2):
        if fm_bytes(g, step_deg, moves) <= budget_mb * 1e6:
            best = g
    if best is None:
        raise ValueError(f"experiment.fm_memory_mb = {budget_mb} holds no grid of side >= 8")
    return best


def c20_weights(units: int, axes: int = len(AXES)) -> torch.Tensor:
    """Hard-wired PPCc -> PMCm weights ``(1 + 2 axes, axes * units^2)``: per axis the upper triangle
    (current angle larger than the target; rows = PPCt, columns = PPCp) to that axis's -step unit,
    the lower triangle to +step, each diagonal with weight 1/axes to "still"."""
    r = torch.arange(units).view(units, 1).expand(units, units)
    c = torch.arange(units).view(1, units).expand(units, units)
    upper, lower, diag = (r < c).float().reshape(-1), (r > c).float().reshape(-1), (r == c).float().reshape(-1)
    W = torch.zeros(1 + 2 * axes, axes * units * units)
    for a in range(axes):
        sl = slice(a * units * units, (a + 1) * units * units)
        W[0, sl] = diag / axes
        W[1 + 2 * a, sl] = upper
        W[2 + 2 * a, sl] = lower
    return W


class Rotation3D(nn.Module):
    """The Experiment 6 network for ``P`` participants (``generators``: one per participant)."""

    def __init__(self, p, side: int, generators: Sequence[torch.Generator]) -> None:
        super().__init__()
        self.p, self.side, self.n = p, int(side), int(side) ** 3
        self.radius = receptive_radius(side, p.step_deg)
        self.moves = move_angles(float(p.step_deg))
        self.fm = nn.ModuleList([LocalConnection(side, self.radius, generators, init=(0.0, p.init_high),
                                                 rules=Delta(p.eta_fm), name=f"FM_{m}") for m in MOVES])
        nu = len(p.posture_angles)
        kw = dict(shape=(nu,), n_in=self.n, generators=generators, init=(0.0, p.init_high), eta=p.eta_posture,
                  sigma=p.posture_sigma, eta_final=p.eta_posture, sigma_final=p.posture_sigma,
                  iterations=p.posture_iterations, supervised=True, readout="dot")
        self.c16 = nn.ModuleList([SOM(name=f"C16_{a}", **kw) for a in AXES])
        self.c17 = nn.ModuleList([SOM(name=f"C17_{a}", **kw) for a in AXES])
        for som in (*self.c16, *self.c17):  # eq. 6.16's unit-sum normalisation belongs to the dot read-out
            som.rule.normalise = p.posture_readout == "dot"
        self.ppc = PopulationMap("PPC", (nu,), 0.0, float(nu - 1), sigma=p.ppc_sigma)
        self.c20 = HardWired(c20_weights(nu), name="C20")
        self.pmcd = LeakyCompetingAccumulator(2, k=p.lca_k, w=p.lca_w, threshold=p.lca_threshold, dt=p.lca_dt)

    @property
    def participants(self) -> int:
        return self.fm[0].weight.shape[0]

    # ------------------------------------------------------------------ pieces
    def predict(self, x: torch.Tensor, move: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """POCi rows ``(R, n)`` -> POCp: the forward model of each row's move, units over 0.5."""
        out = torch.zeros_like(x)
        for m, conn in enumerate(self.fm):
            sel = (move == m).nonzero().squeeze(-1)
            if sel.numel():
                out[sel] = (conn.net_binary(x[sel], part[sel]) + 1.0 > 1.5).float()
        return out

    def postures(self, soms, x: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """Winning posture unit per axis of rows ``x`` -> ``(R, axes)``: ``posture_readout='dot'`` the
        arg-max of ``W x`` (eq. 6.14), ``'distance'`` the prototype nearest in Euclidean distance."""
        out = []
        for som in soms:
            W = som.weight  # (P, units, n)
            score = torch.einsum("rn,run->ru", x, W[part])
            if self.p.posture_readout == "distance":
                score = score - 0.5 * (W * W).sum(-1)[part]  # arg-max of x.w - |w|^2 / 2 = arg-min |x - w|
            out.append(score.argmax(-1))
        return torch.stack(out, -1)

    def ppc_code(self, units: torch.Tensor, proprioception: str = "none") -> torch.Tensor:
        """Gaussian bumps ``(R, axes, nu)`` around the winners ``(R, axes)``, plus the wrist signal.

        The wrist turns about the line of sight (:data:`WRIST_AXIS`), as the Exp 4 hand turns in the
        picture plane: ``match`` adds ``proprio_gain`` times a bump on that axis's winner,
        ``mismatch`` on the opposite unit ``nu - 1 - j``; summed with the image-derived bump, then
        cut to [0, 1] (Exp 4's ``proprio_stage='visual'``).
        """
        check_proprioception(proprioception)
        code = self.ppc.encode(units.float())
        if proprioception == "none":
            return code
        a, nu = AXES.index(WRIST_AXIS), code.shape[-1]
        j = units[:, a] if proprioception == "match" else nu - 1 - units[:, a]
        code[:, a] = (code[:, a] + self.p.proprio_gain * self.ppc.encode(j.float())).clamp(0.0, 1.0)
        return code

    def select(self, ppct: torch.Tensor, ppcp: torch.Tensor, uniforms: torch.Tensor) -> torch.Tensor:
        """PMCm move per row from the per-axis gain fields (eq. 6.9-6.11)."""
        R, A, nu = ppct.shape
        ppcc = torch.stack([gain_field(ppct[:, a], ppcp[:, a]) for a in range(A)], 1)  # (R, A, nu, nu)
        am = self.c20(ppcc.reshape(R, A * nu * nu))
        return softmax_select(am, self.p.softmax_tau, uniforms=uniforms)

    # ------------------------------------------------------------------ trials
    @torch.no_grad()
    def run(self, target: torch.Tensor, rotated: torch.Tensor, generators, record: int = 0,
            proprioception: str = "none") -> dict:
        """Trials ``(P, B, n)`` of binary 3-D maps; randomness from ``generators`` (one per participant,
        one ``(B,)`` draw per step in a fixed order, so a result does not depend on the batch).
        ``record``: leading trials of participant 0 whose maps are returned per step;
        ``proprioception``: the wrist signal on PPCp (:meth:`ppc_code`)."""
        p = self.p
        P, B, n = target.shape
        check_proprioception(proprioception)  # before any work
        if len(generators) != P:
            raise ValueError(f"{len(generators)} generators for {P} participants")
        Q = P * B
        part = torch.arange(P).repeat_interleave(B)
        pfct = target.reshape(Q, n)
        pfct_near = voxels.dilate(pfct, self.side, p.match_radius)
        pfcft = voxels.principal_reflection(pfct, self.side)  # C10
        pfcft_near = voxels.dilate(pfcft, self.side, p.match_radius)
        t_count = pfct.sum(-1)
        ppct = self.ppc_code(self.postures(self.c17, pfct, part))  # (Q, A, nu)
        gain = lca_gain(p)

        def evidence(rows, pocp):
            tm = pocp * pfct_near[rows]
            fm = pocp * pfcft_near[rows]
            size = torch.maximum(t_count[rows], pocp.sum(-1)).clamp_min(1.0).unsqueeze(-1)
            return gain * torch.stack([tm.sum(-1), fm.sum(-1)], -1) / size, tm, fm

        winner = torch.full((Q,), -1, dtype=torch.long)
        rt = torch.zeros(Q, dtype=torch.long)
        steps = torch.zeros(Q, dtype=torch.long)
        turned = torch.zeros(Q, len(AXES))  # net mental rotation per axis (deg)
        hist: list[list[dict]] = [[] for _ in range(min(record, B))]
        # step 1: "still" on every trial
        q = torch.arange(Q)
        poci = rotated.reshape(Q, n)
        pocp = self.predict(poci, torch.zeros(Q, dtype=torch.long), part)
        ev, tm, fm = evidence(q, pocp)
        y = self.pmcd.initial_state((Q,))
        move = torch.zeros(Q, dtype=torch.long)
        for s in range(p.max_steps):
            if s > 0:
                draws = torch.stack([torch.rand(B, generator=g) for g in generators]).reshape(Q)
                ppcp = self.ppc_code(self.postures(self.c16, poci, part[q]), proprioception)
                move = self.select(ppct[q], ppcp, draws[q])
                pocp = self.predict(poci, move, part[q])
                ev, tm, fm = evidence(q, pocp)
                for a in range(len(AXES)):
                    for sign, m in ((-1.0, 1 + 2 * a), (1.0, 2 + 2 * a)):
                        turned[q, a] += sign * p.step_deg * (move == m).float()
            dec = self.pmcd(ev, p.lca_cycles, state=y)
            steps[q] += 1
            rt[q] += dec.cycles
            winner[q] = torch.where(dec.decided, dec.winner, winner[q])
            for k in range(len(hist)):
                hit = (q == k).nonzero()
                if hit.numel():
                    i = int(hit[0])
                    maps = {"PFCt": pfct[k], "PFCft": pfcft[k], "POCi": poci[i], "POCp": pocp[i], "PFCtm": tm[i],
                            "PFCfm": fm[i], "PMCm": torch.nn.functional.one_hot(move[i], len(MOVES)).float(),
                            "PMCd": dec.state[i]}
                    hist[k].append({n: m.clone() for n, m in maps.items()})  # a view would pin the batch's step
            keep = ~dec.decided
            q, poci, y = q[keep], pocp[keep], dec.state[keep]
            if q.numel() == 0:
                break
        coin = torch.stack([torch.rand(B, generator=g) for g in generators]).reshape(Q)
        timeout = winner < 0
        answer = torch.where(timeout, (coin < 0.5).long(), winner)
        sh = (P, B)
        return {"answer": answer.reshape(sh), "rt": rt.reshape(sh), "rotation_steps": (steps - 1).reshape(sh),
                "decided": (~timeout).reshape(sh), "turned": turned.reshape(P, B, len(AXES)), "history": hist}
