"""The fused trials of the Experiment 4 model: the same pairs ``(P, B, n)`` under several wrist
conditions, computed as one batch (:meth:`RotationEmbodied.run_conditions`).

The first step (always "still") and everything about the target do not depend on the condition,
so they are computed once. After that the trials are kept as a flat list of (condition,
participant, trial) rows and only undecided rows are carried to the next step. Each condition
draws its random numbers from its own generators, one ``(B,)`` draw per participant and step, so
a result does not depend on what else is in the batch. The binary maps of the step loop are
packed rows (:mod:`neuroimagery.nn.binary`): overlaps are bit counts, and a forward-model
prediction is computed once per distinct (participant, move, image) of a step.
"""
from __future__ import annotations

import torch

from ..nn import population_cover
from ..nn.binary import pack_bits, popcount, unique_rows, unpack_bits
from ..nn.functional import gain_field, softmax_select
from ..nn.readout import binary_rows
from .recording import first_rows, sample_indices

STILL = 1  # the index of Ms, the "still" move, in (Ml, Ms, Mr)


class FusedTrials:
    """One call of :meth:`RotationEmbodied.run_conditions`: the target side, the results ``(C, Q)``
    (Q = P * B flat trials) and the recorded histories of participant 0's sample trials."""

    def __init__(self, model, target: torch.Tensor, rotated: torch.Tensor, conditions, record, flipped):
        self.m, self.p, self.conditions = model, model.p, conditions
        P, B, n = target.shape
        self.P, self.B, self.n, self.Q = P, B, n, P * B
        C, nu, Q = len(conditions), len(self.p.ppc.angles), P * B
        self.nu = nu
        self.part = torch.arange(P).repeat_interleave(B)  # participant of each base row
        # the target side (PFCt, PPCt, PFCft): shared by every condition
        self.pfct = target.reshape(Q, n)
        ppct_unit = model.posture(model.c17, target)
        self.ppct = model.ppc.encode(ppct_unit.float()).reshape(Q, nu)
        if flipped is None:
            flipped = model.flipped(target, ppct_unit)
        self.reach = int(self.p.match_tolerance)
        self.pfcft = flipped.reshape(Q, n)
        self.pfct_w, self.pfcft_w = pack_bits(self.pfct), pack_bits(self.pfcft)
        self.t_count = self.pfct.sum(-1).clamp_min(1.0)
        self.step_deg = torch.tensor(model.step_angles)
        self.rotated = rotated.reshape(Q, n)
        self.gain, self.leak = model.input_gain[self.part], model.leak[self.part]  # (Q,) per participant
        # results, (C, Q)
        self.winner = torch.full((C, Q), -1, dtype=torch.long)
        self.rt = torch.zeros(C, Q, dtype=torch.long)
        self.steps = torch.zeros(C, Q, dtype=torch.long)
        self.rotations = torch.zeros(C, Q, dtype=torch.long)
        self.angle = torch.zeros(C, Q)
        shown = sample_indices(record, B)
        self.histories: list[list[list[dict]]] = [[[] for _ in shown] for _ in range(C)]
        self.rec = list(zip(shown, range(len(shown))))  # (flat row q of participant 0, history slot)

    def unpack(self, w: torch.Tensor) -> torch.Tensor:
        return unpack_bits(w, self.n).float()  # a recorded map

    def evidence(self, rows_q, cover_w):
        """PFCtm / PFCfm: the target (flipped target) units that POCp covers, read as a population
        code of reach ``match_tolerance`` (one-to-one inputs above 1.5 at reach 0)."""
        tm, fm = self.pfct_w[rows_q] & cover_w, self.pfcft_w[rows_q] & cover_w
        ev = torch.stack([popcount(tm).float(), popcount(fm).float()], -1) / self.t_count[rows_q].unsqueeze(-1)
        return self.gain[rows_q].unsqueeze(-1) * ev, tm, fm

    def predict(self, group, poci_w):
        """POCp (packed), what it covers (packed) and its C16 activation potentials PPCpA (eq. 6.14)
        for the forward models ``group`` (participant * 3 + move), once per distinct pair."""
        g, words, inv = unique_rows(group, poci_w)
        pocp = binary_rows(self.m.fm, g, unpack_bits(words, self.n)) + 1.0 > 1.5
        cover = population_cover(pocp, self.m.size, self.reach)  # bool
        return pack_bits(pocp)[inv], pack_bits(cover)[inv], self.m.c16.net_binary(pocp, g // 3)[inv]

    def first_step(self):
        """Step 1: the "still" forward model on every trial, identical in every condition; returns
        the condition rows of the undecided trials (q, cond, POCi, PPCpA, PMCd state)."""
        Q, C = self.Q, len(self.conditions)
        still = torch.full((Q,), STILL, dtype=torch.long)
        pocp0, cover0, score0 = self.predict(self.part * 3 + STILL, pack_bits(self.rotated))
        ev0, tm0, fm0 = self.evidence(torch.arange(Q), cover0)
        dec = self.m.pmcd(ev0, self.p.lca.cycles, state=self.m.pmcd.initial_state((Q,)), leak=self.leak)
        self.steps += 1
        self.rt += dec.cycles
        self.winner[:] = torch.where(dec.decided, dec.winner, self.winner[0])
        for c in range(C):
            for q, k in self.rec:
                self.histories[c][k].append(self.m._snapshot(
                    self.pfct[q], self.pfcft[q], self.rotated[q], self.unpack(pocp0[q]), self.ppct[q], None,
                    still[q], self.unpack(tm0[q]), self.unpack(fm0[q]), dec.state[q]))
        live_q = (~dec.decided).nonzero().squeeze(-1)
        q = live_q.repeat(C)
        return q, torch.arange(C).repeat_interleave(live_q.numel()), pocp0[q], score0[q], dec.state[q]

    def moves(self, q, cond, score) -> torch.Tensor:
        """The next movement of every live row from the wrist postures (eq. 6.9-6.11), per condition;
        every condition draws its numbers whether or not it has live rows."""
        B, Q, nu, p = self.B, self.Q, self.nu, self.p
        move = torch.empty_like(q)
        for c, (prop, noisy, gens) in enumerate(self.conditions):
            sel = cond == c
            draws_noise = [torch.rand(B, nu, generator=g) for g in gens] if noisy else None
            draws_sel = torch.stack([torch.rand(B, generator=g) for g in gens]).reshape(Q)
            draws_win = torch.stack([torch.rand(B, generator=g) for g in gens]).reshape(Q) if p.posture.tau > 0 else None
            if not bool(sel.any()):
                continue
            qc = q[sel]
            jc = self.m.posture_winner(score[sel], None if draws_win is None else draws_win[qc])
            ppcp = self.m.ppcp_code(jc, prop, torch.stack(draws_noise).reshape(Q, nu)[qc] if noisy else None)
            ppcc = gain_field(self.ppct[qc], ppcp)  # rows PPCt, columns PPCp
            am = self.m.pmcm_input(ppcc.reshape(-1, nu * nu))
            move[sel] = softmax_select(am, p.selection.tau, uniforms=draws_sel[qc])
            if self.rec:
                self.m._note_ppc(self.histories[c], self.rec, qc, ppcp, ppcc)
        return move

    def step(self, q, cond, poci, score, y):
        """One imagined step of the live rows: move, forward model, overlap, accumulator; returns the
        rows still undecided."""
        move = self.moves(q, cond, score)
        pocp, cover, score = self.predict(self.part[q] * 3 + move, poci)
        ev, tm, fm = self.evidence(q, cover)
        dec = self.m.pmcd(ev, self.p.lca.cycles, state=y, leak=self.leak[q])
        self.angle[cond, q] += self.step_deg[move]
        self.rotations[cond, q] += (move != STILL).long()
        self.steps[cond, q] += 1
        self.rt[cond, q] += dec.cycles
        self.winner[cond, q] = torch.where(dec.decided, dec.winner, self.winner[cond, q])
        for c in range(len(self.conditions)):
            rows = (cond == c).nonzero().squeeze(-1) if self.rec else None
            for j, k in first_rows(q[rows], self.rec) if self.rec else ():
                i, qq = int(rows[j]), int(q[rows[j]])
                self.histories[c][k].append(self.m._snapshot(
                    self.pfct[qq], self.pfcft[qq], self.unpack(poci[i]), self.unpack(pocp[i]), self.ppct[qq], None,
                    move[i], self.unpack(tm[i]), self.unpack(fm[i]), dec.state[i]))
        keep = ~dec.decided
        return q[keep], cond[keep], pocp[keep], score[keep], dec.state[keep]

    def run(self) -> list[dict]:
        rows = self.first_step()
        for _ in range(self.p.selection.max_steps - 1):
            if rows[0].numel() == 0:
                break
            rows = self.step(*rows)
        return [self.result(c, gens) for c, (_, _, gens) in enumerate(self.conditions)]

    def result(self, c: int, gens) -> dict:
        """Condition ``c``'s answers: a trial that timed out answers at random (one draw per trial)."""
        coin = torch.stack([torch.rand(self.B, generator=g) for g in gens]).reshape(self.Q)
        timeout = self.winner[c] < 0
        answer = torch.where(timeout, (coin < 0.5).long(), self.winner[c])
        shape = (self.P, self.B)
        return {"answer": answer.reshape(shape), "rt": self.rt[c].reshape(shape),
                "rotation_steps": (self.steps[c] - 1).reshape(shape), "rotations": self.rotations[c].reshape(shape),
                "rotation_deg": self.angle[c].reshape(shape), "decided": (~timeout).reshape(shape),
                "history": self.histories[c]}
