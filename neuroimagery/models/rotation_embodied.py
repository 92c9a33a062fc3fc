"""Experiment 4 model: mental rotation with forward models, wrist-posture maps, a leaky competing
accumulator and proprioception (thesis section 6.2, Fig. 6.7, Tables 6.1-6.2).

Maps (Table 6.1), all batched ``(P, B, n)``:

* POCi, POCl/POCs/POCr, POCp (32x32): current mental image, the three candidate rotations, the
  selected prediction;
* PFCt, PFCft (32x32): target and flipped target (working memory); PFCtm, PFCfm: their overlap
  with POCp (sum of the one-to-one inputs thresholded at 1.5);
* PPCp, PPCt (6 units): wrist posture of the mental image / of the target (eq. 6.14);
  PPCc (6x6) their gain field (eq. 6.9);
* PMCm (3 units: Ml, Ms, Mr) from PPCc through hard-wired weights (eq. 6.10) and softmax
  selection (eq. 6.11); PMCd (2 units: yes, no) a leaky competing accumulator (eq. 6.12-6.13).

Connections: C1-C3 forward models (AllToAll, delta rule eq. 6.4), C16/C17 supervised Kohonen maps
(eq. 6.14-6.16), PMCm hard-wired (C20), the rest fixed relays.

Conventions: angles are counter-clockwise positive (as the stimuli). PPC units are ordered by
increasing angle (``ppc_angles``); with PPCc rows = PPCt and columns = PPCp the 15 units above
the diagonal (current angle larger than the target) drive Mr, a clockwise turn (-step), and the
15 below drive Ml, a counter-clockwise turn (+step).
"""
from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from ..nn import AllToAll, Delta, HardWired, LeakyCompetingAccumulator, PopulationMap, SOM
from ..nn.functional import gain_field, softmax_select
from ..experiments.protocol_ch6 import binary_matmul

MOVES = ("Ml", "Ms", "Mr")


def triangle_weights(n: int) -> torch.Tensor:
    """Hard-wired PPCc -> PMCm weights ``(3, n*n)`` (eq. 6.10): lower -> Ml, diagonal -> Ms, upper -> Mr."""
    r = torch.arange(n).view(n, 1).expand(n, n)
    c = torch.arange(n).view(1, n).expand(n, n)
    return torch.stack([(r > c), (r == c), (r < c)]).reshape(3, n * n).float()


def reflection_index(size: int, axis_deg: float) -> torch.Tensor:
    """Source pixel of every destination pixel for a reflection of a ``size x size`` map about the
    line through its centre at ``axis_deg`` (counter-clockwise from the x axis, as seen on screen).
    Pixels whose source falls outside get index ``size*size`` (a zero pad)."""
    c = (size - 1) / 2.0
    ys, xs = torch.meshgrid(torch.arange(size, dtype=torch.float64), torch.arange(size, dtype=torch.float64), indexing="ij")
    t = math.radians(axis_deg)
    dx, dy = xs - c, -(ys - c)  # y up
    cos2, sin2 = math.cos(2 * t), math.sin(2 * t)
    sx, sy = cos2 * dx + sin2 * dy, sin2 * dx - cos2 * dy
    col, row = torch.round(sx + c).long(), torch.round(c - sy).long()
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    return torch.where(ok, row * size + col, torch.full_like(col, size * size)).reshape(-1)


class RotationEmbodied(nn.Module):
    """The Experiment 4 network for ``P`` participants (``generators``: one per participant)."""

    def __init__(self, p, generators: Sequence[torch.Generator]) -> None:
        super().__init__()
        self.p = p
        n = p.map_size * p.map_size
        self.n, self.size = n, p.map_size
        self.step_angles = (float(p.step_deg), 0.0, -float(p.step_deg))  # Ml, Ms, Mr
        self.fm = nn.ModuleList([
            AllToAll(n, n, init=(0.0, p.init_high), generators=generators, rules=Delta(p.eta_fm), name=f"C{k + 1}")
            for k in range(3)])
        nu = len(p.ppc_angles)
        kw = dict(shape=(nu,), n_in=n, generators=generators, init=(0.0, p.init_high), eta=p.eta_posture,
                  sigma=p.posture_sigma, eta_final=p.eta_posture_final, sigma_final=p.posture_sigma,
                  iterations=p.posture_iterations, supervised=True, readout="dot")
        self.c16 = SOM(name="C16", **kw)
        self.c17 = SOM(name="C17", **kw)
        self.ppc = PopulationMap("PPC", (nu,), 0.0, float(nu - 1), sigma=p.ppc_sigma)
        self.c20 = HardWired(triangle_weights(nu), name="C20")
        self.pmcd = LeakyCompetingAccumulator(2, k=p.lca_k, w=p.lca_w, threshold=p.lca_threshold, dt=p.lca_dt)
        flips = torch.stack([reflection_index(p.map_size, 90.0 + a) for a in p.ppc_angles])
        self.register_buffer("flip_index", flips)  # (units, n) hard-wired C10 per target posture
        self._tables: list[torch.Tensor] | None = None

    # ------------------------------------------------------------------ learning
    def freeze(self) -> None:
        """Cache the transposed forward-model weights used by the binary fast path."""
        self._tables = [c.weight.transpose(1, 2).contiguous() for c in self.fm]

    def posture(self, som: SOM, x: torch.Tensor) -> torch.Tensor:
        """Winning wrist-posture unit of an image (eq. 6.14: argmax of ``W x``) -> long ``(P, B)``."""
        return torch.bmm(x, som.weight.transpose(1, 2)).argmax(-1)

    def forward_step(self, x: torch.Tensor, move: torch.Tensor, active: torch.Tensor | None = None) -> torch.Tensor:
        """POCi -> POCp: the forward model chosen by ``move`` ``(P, B)`` (0 Ml, 1 Ms, 2 Mr).

        A POCl/s/r unit fires when its PMCm unit (1) plus its forward-model input exceeds 1.5,
        i.e. when the prediction exceeds 0.5; only the selected map can fire.
        """
        if self._tables is None:
            self.freeze()
        out = torch.zeros_like(x)
        for m in range(3):
            sel = move == m
            if active is not None:
                sel = sel & active
            if not bool(sel.any()):
                continue
            pred = binary_matmul(self._tables[m], x * sel.unsqueeze(-1))
            out = torch.where(sel.unsqueeze(-1), (pred + 1.0 > 1.5).float(), out)
        return out

    def flipped(self, target: torch.Tensor, ppct_unit: torch.Tensor) -> torch.Tensor:
        """PFCft: the target reflected about the main axis of the orientation PPCt encodes (C10)."""
        pad = torch.cat([target, torch.zeros(*target.shape[:-1], 1)], dim=-1)
        return torch.gather(pad, -1, self.flip_index[ppct_unit])

    # ------------------------------------------------------------------ trials
    @torch.no_grad()
    def run(self, target: torch.Tensor, rotated: torch.Tensor, generators, proprioception: str = "none",
            noise: bool = False, record: int = 0, flipped: torch.Tensor | None = None) -> dict:
        """Run a batch of trials. ``target``/``rotated``: binary edge maps ``(P, B, n)``.

        ``proprioception``: ``none``, ``match`` (wrist signal on the PPCp unit of the mental
        rotation) or ``mismatch`` (on the opposite unit, ``units-1-j``). ``noise`` adds
        U[-a, a] per PPCp unit and step (clipped to [0, 1]). Randomness (softmax selection, noise,
        time-out answers) comes from ``generators``, one per participant, drawn in a fixed order.
        ``record``: number of leading trials of participant 0 whose maps are returned per step.
        """
        p = self.p
        if proprioception not in ("none", "match", "mismatch"):
            raise ValueError(f"proprioception must be none, match or mismatch, got {proprioception!r}")
        P, B, _ = target.shape
        nu = len(p.ppc_angles)
        pfct = target
        ppct_unit = self.posture(self.c17, pfct)
        ppct = self.ppc.encode(ppct_unit.float())  # (P, B, nu)
        pfcft = self.flipped(pfct, ppct_unit) if flipped is None else flipped
        t_count = pfct.sum(-1).clamp_min(1.0)
        poci = rotated
        move = torch.ones(P, B, dtype=torch.long)  # the first step is always "still"
        y = self.pmcd.initial_state((P, B))
        done = torch.zeros(P, B, dtype=torch.bool)
        winner = torch.full((P, B), -1, dtype=torch.long)
        rt = torch.zeros(P, B, dtype=torch.long)
        steps = torch.zeros(P, B, dtype=torch.long)
        rotations = torch.zeros(P, B, dtype=torch.long)
        angle = torch.zeros(P, B)
        step_deg = torch.tensor(self.step_angles)
        history: list[list[dict]] = [[] for _ in range(min(record, B))]
        for s in range(p.max_steps):
            act = ~done
            if not bool(act.any()):
                break
            pocp = self.forward_step(poci, move, act)
            pocp = torch.where(act.unsqueeze(-1), pocp, poci)
            angle = angle + torch.where(act, step_deg[move], torch.zeros(()))
            rotations = rotations + (act & (move != 1)).long()
            steps = steps + act.long()
            tm = (pfct + pocp > 1.5).float()
            fm = (pfcft + pocp > 1.5).float()
            evidence = p.lca_input_gain * torch.stack([tm.sum(-1), fm.sum(-1)], -1) / t_count.unsqueeze(-1)
            dec = self.pmcd(evidence, p.lca_cycles, state=y, active=act)
            y = dec.state
            new = dec.decided & act
            rt = rt + torch.where(act, dec.cycles, torch.zeros_like(dec.cycles))
            winner = torch.where(new, dec.winner, winner)
            # next movement from the wrist postures (eq. 6.9-6.11)
            j = self.posture(self.c16, pocp)
            ppcp = self.ppc.encode(j.float())
            if proprioception != "none":
                wrist = j if proprioception == "match" else (nu - 1 - j)
                ppcp = ppcp + p.proprio_gain * self.ppc.encode(wrist.float())
            if noise:
                u = torch.stack([torch.rand(B, nu, generator=g) for g in generators])
                ppcp = ppcp + (2 * u - 1) * p.noise_amplitude
            ppcp = ppcp.clamp(0.0, 1.0)
            ppcc = gain_field(ppct, ppcp)  # (P, B, nu, nu): rows PPCt, columns PPCp
            am = self.c20(ppcc.reshape(P, B, nu * nu))
            nxt = softmax_select(am, p.softmax_tau, generators)
            for k in range(len(history)):
                if bool(act[0, k]):
                    history[k].append({
                        "PFCt": pfct[0, k].view(self.size, self.size), "PFCft": pfcft[0, k].view(self.size, self.size),
                        "POCi": poci[0, k].view(self.size, self.size), "POCp": pocp[0, k].view(self.size, self.size),
                        "PPCt": ppct[0, k], "PPCp": ppcp[0, k], "PPCc": ppcc[0, k],
                        "PMCm": torch.nn.functional.one_hot(move[0, k], 3).float(),
                        "PFCtm": tm[0, k].view(self.size, self.size), "PFCfm": fm[0, k].view(self.size, self.size),
                        "PMCd": y[0, k].clone()})
            done = done | new
            move = torch.where(done, move, nxt)
            poci = pocp
        # time-out: a random answer
        coin = torch.stack([torch.rand(B, generator=g) for g in generators])
        timeout = winner < 0
        answer = torch.where(timeout, (coin < 0.5).long(), winner)
        return {"answer": answer, "rt": rt, "rotation_steps": steps - 1, "rotations": rotations,
                "rotation_deg": angle, "decided": ~timeout, "history": history}
