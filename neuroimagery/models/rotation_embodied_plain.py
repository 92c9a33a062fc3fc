"""The Experiment 4 trial (thesis 6.2, Fig. 6.7) written plainly: one participant and one trial
at a time, every product a dense matrix-vector product, the equations in the order the thesis
gives them. :meth:`RotationEmbodied.run_conditions` computes the same trials fused (rows of all
participants, trials and conditions together, binary products as sums of weight rows, undecided
rows only); this is its reference (``tests/test_exp4.py`` holds one against the other). It draws
the same random numbers in the same order, so the answers, cycles and steps are the same."""
from __future__ import annotations

import torch

from ..nn.functional import gain_field, softmax_select


class _PlainTrials:
    """The maps of one plain call: the target side, the results and the live trials."""

    def __init__(self, model, target: torch.Tensor, rotated: torch.Tensor, proprioception: str, noise: bool):
        self.m, self.p, self.target, self.rotated = model, model.p, target, rotated
        self.prop, self.noise = proprioception, noise
        P, B, _ = target.shape
        self.B, self.nu = B, len(self.p.ppc.angles)
        self.ppct_unit = model.posture(model.c17, target)  # PPCt winner (eq. 6.14), (P, B)
        self.flipped = model.flipped(target, self.ppct_unit)
        self.out = {k: torch.zeros(P, B, dtype=torch.long) for k in ("answer", "rt", "rotation_steps", "rotations")}
        self.out["rotation_deg"] = torch.zeros(P, B)
        self.out["decided"] = torch.zeros(P, B, dtype=torch.bool)

    def predict(self, m: int, pi: int, x: torch.Tensor) -> torch.Tensor:
        """POCl/s/r: PMCm unit (1) + forward-model input > 1.5 (Table 6.2)."""
        return (self.m.fm[m].net_of(pi, x) + 1.0 > 1.5).float()  # C1-C3: Ml, Ms, Mr

    def decide(self, pi: int, b: int, pocp: torch.Tensor, y):
        """PFCtm, PFCfm (the target units POCp covers), the evidence and ``lca.cycles`` cycles of
        PMCd (eq. 6.12-6.13); the trial's RT counts them, and a decision ends the trial. Returns the
        live state ``[p, b, POCi, PMCd state, C16 potentials]`` of an undecided trial, else None."""
        m, t, f = self.m, self.target[pi, b], self.flipped[pi, b]
        tm, fmm = m.overlap(t, pocp), m.overlap(f, pocp)  # POCp read as a population code
        ev = m.input_gain[pi] * torch.stack([tm, fmm]) / t.sum().clamp_min(1.0)
        d = m.pmcd(ev.unsqueeze(0), self.p.lca.cycles, state=y, leak=m.leak[pi].reshape(1))
        self.out["rt"][pi, b] += int(d.cycles[0])
        if bool(d.decided[0]):
            self.out["answer"][pi, b], self.out["decided"][pi, b] = int(d.winner[0]), True
            return None
        return [pi, b, pocp, d.state, m.c16.net_of(pi, pocp)]

    def draws(self, generators) -> list[tuple]:
        """Every participant draws (B,) per step, decided trials or not, as the fused form."""
        out = []
        for g in generators:
            u_noise = torch.rand(self.B, self.nu, generator=g) if self.noise else None
            u_sel = torch.rand(self.B, generator=g)
            u_win = torch.rand(self.B, generator=g) if self.p.posture.tau > 0 else None
            out.append((u_noise, u_sel, u_win))
        return out

    def step(self, trial: list, draws: tuple):
        """One imagined step of a live trial: PPCp, PPCc, PMCm's draw, the forward model, PMCd."""
        m, p, nu = self.m, self.p, self.nu
        pi, b, poci, y, score = trial
        u_noise, u_sel, u_win = draws
        j = m.posture_winner(score.unsqueeze(0), None if u_win is None else u_win[b:b + 1])  # PPCp winner
        ppcp = m.ppcp_code(j, self.prop, None if u_noise is None else u_noise[b:b + 1])
        ppct = m.ppc.encode(self.ppct_unit[pi, b:b + 1].float())
        ppcc = gain_field(ppct, ppcp)  # PPCc (eq. 6.9): rows PPCt, columns PPCp
        am = m.pmcm_input(ppcc.reshape(1, nu * nu))  # PMCm input (eq. 6.10, rule R3)
        move = int(softmax_select(am, p.selection.tau, uniforms=u_sel[b:b + 1])[0])  # eq. 6.11
        self.out["rotation_deg"][pi, b] += m.step_angles[move]
        self.out["rotations"][pi, b] += int(move != 1)
        self.out["rotation_steps"][pi, b] += 1
        return self.decide(pi, b, self.predict(move, pi, poci), y)


@torch.no_grad()
def run_plain(model, target: torch.Tensor, rotated: torch.Tensor, generators, proprioception: str = "none",
              noise: bool = False) -> dict:
    """:meth:`RotationEmbodied.run` of ``model`` for ``target`` / ``rotated`` ``(P, B, n)``, plainly."""
    t = _PlainTrials(model, target, rotated, proprioception, noise)
    P, B, _ = target.shape
    live = [t.decide(pi, b, t.predict(1, pi, rotated[pi, b]), model.pmcd.initial_state((1,)))
            for pi in range(P) for b in range(B)]  # step 1: the "still" forward model, from rest
    live = [x for x in live if x is not None]
    for _ in range(model.p.selection.max_steps - 1):
        if not live:
            break
        draws = t.draws(generators)
        live = [x for x in (t.step(trial, draws[trial[0]]) for trial in live) if x is not None]
    for pi, g in enumerate(generators):  # a time-out answers at random
        coin = torch.rand(B, generator=g)
        for b in range(B):
            if not t.out["decided"][pi, b]:
                t.out["answer"][pi, b] = int(coin[b] < 0.5)
    return t.out
