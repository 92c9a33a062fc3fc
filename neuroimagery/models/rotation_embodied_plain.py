"""The Experiment 4 trial (thesis 6.2, Fig. 6.7) written plainly: one participant and one trial
at a time, every product a dense matrix-vector product, the equations in the order the thesis
gives them. :meth:`RotationEmbodied.run_conditions` computes the same trials fused (rows of all
participants, trials and conditions together, binary products as sums of weight rows, undecided
rows only); this is its reference (``tests/test_exp4.py`` holds one against the other). It draws
the same random numbers in the same order, so the answers, cycles and steps are the same."""
from __future__ import annotations

import torch

from ..nn.functional import gain_field, softmax_select


@torch.no_grad()
def run_plain(model, target: torch.Tensor, rotated: torch.Tensor, generators, proprioception: str = "none",
              noise: bool = False) -> dict:
    """:meth:`RotationEmbodied.run` of ``model`` for ``target`` / ``rotated`` ``(P, B, n)``, plainly."""
    p, (P, B, _) = model.p, target.shape
    nu = len(p.ppc.angles)
    gain = model.input_gain  # PMCd's input gain per participant (fixed after training)
    ppct_unit = model.posture(model.c17, target)  # PPCt winner (eq. 6.14), (P, B)
    if p.flip_axis == "ppct":
        flipped = model.flipped(target, ppct_unit)
    else:
        flipped = model.flipped_image(target)
    out = {k: torch.zeros(P, B, dtype=torch.long) for k in ("answer", "rt", "rotation_steps", "rotations")}
    out["rotation_deg"] = torch.zeros(P, B)
    out["decided"] = torch.zeros(P, B, dtype=torch.bool)
    trials = []  # the live state of each trial: [p, b, POCi, PMCd state, C16 potentials, winner]

    def predict(m: int, pi: int, x: torch.Tensor) -> torch.Tensor:
        """POCl/s/r: PMCm unit (1) + forward-model input > 1.5 (Table 6.2)."""
        return (model.fm[m].net_of(pi, x) + 1.0 > 1.5).float()  # C1-C3: Ml, Ms, Mr

    def decide(pi: int, b: int, pocp: torch.Tensor, y):
        """PFCtm, PFCfm (the target units POCp covers), the evidence and ``lca.cycles`` cycles of PMCd (eq. 6.12-6.13)."""
        t, f = target[pi, b], flipped[pi, b]
        tm, fmm = model.overlap(t, pocp), model.overlap(f, pocp)  # POCp read as a population code
        ev = gain[pi] * torch.stack([tm, fmm]) / t.sum().clamp_min(1.0)
        return model.pmcd(ev.unsqueeze(0), p.lca.cycles, state=y, leak=model.leak[pi].reshape(1))

    for pi in range(P):  # step 1: the "still" forward model, from rest
        for b in range(B):
            pocp = predict(1, pi, rotated[pi, b])
            d = decide(pi, b, pocp, model.pmcd.initial_state((1,)))
            out["rt"][pi, b] += int(d.cycles[0])
            if bool(d.decided[0]):
                out["answer"][pi, b], out["decided"][pi, b] = int(d.winner[0]), True
            else:
                trials.append([pi, b, pocp, d.state, model.c16.net_of(pi, pocp)])
    for _ in range(p.selection.max_steps - 1):
        if not trials:
            break
        draws = []  # every participant draws (B,) per step, decided trials or not, as the fused form
        for g in generators:
            u_noise = torch.rand(B, nu, generator=g) if noise else None
            u_sel = torch.rand(B, generator=g)
            u_win = torch.rand(B, generator=g) if p.posture.tau > 0 else None
            draws.append((u_noise, u_sel, u_win))
        still_live = []
        for pi, b, poci, y, score in trials:
            u_noise, u_sel, u_win = draws[pi]
            j = model.posture_winner(score.unsqueeze(0), None if u_win is None else u_win[b:b + 1])  # PPCp winner
            ppcp = model.ppcp_code(j, proprioception, None if u_noise is None else u_noise[b:b + 1])
            ppct = model.ppc.encode(ppct_unit[pi, b:b + 1].float())
            ppcc = gain_field(ppct, ppcp)  # PPCc (eq. 6.9): rows PPCt, columns PPCp
            am = model.pmcm_input(ppcc.reshape(1, nu * nu))  # PMCm input (eq. 6.10, rule R3)
            move = int(softmax_select(am, p.selection.tau, uniforms=u_sel[b:b + 1])[0])  # eq. 6.11
            pocp = predict(move, pi, poci)
            d = decide(pi, b, pocp, y)
            out["rotation_deg"][pi, b] += model.step_angles[move]
            out["rotations"][pi, b] += int(move != 1)
            out["rotation_steps"][pi, b] += 1
            out["rt"][pi, b] += int(d.cycles[0])
            if bool(d.decided[0]):
                out["answer"][pi, b], out["decided"][pi, b] = int(d.winner[0]), True
            else:
                still_live.append([pi, b, pocp, d.state, model.c16.net_of(pi, pocp)])
        trials = still_live
    for pi, g in enumerate(generators):  # a time-out answers at random
        coin = torch.rand(B, generator=g)
        for b in range(B):
            if not out["decided"][pi, b]:
                out["answer"][pi, b] = int(coin[b] < 0.5)
    return out
