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
increasing angle (``ppc.angles``); with PPCc rows = PPCt and columns = PPCp the 15 units above
the diagonal (current angle larger than the target) drive Mr, a clockwise turn (-step), and the
15 below drive Ml, a counter-clockwise turn (+step).
"""
from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from ..nn import AllToAll, Delta, HardWired, LeakyCompetingAccumulator, PopulationMap, SOM, population_cover
from ..nn.binary import ActiveRows
from ..nn.functional import softmax_select
from ..vision.reflection import reflection_index
from .rotation_embodied_trials import FusedTrials
from ..nn.decision import Decision, full_match_gain, smallest_deciding_gain
from .pmcd_leak import leak_by_rule
from .recording import first_rows
from .posture_ch6 import fit_posture_soms, posture_maps, posture_order  # noqa: F401  (re-exported)
from .rotation_embodied_params import PROPRIOCEPTION, EmbodiedLcaParams, EmbodiedParams, EmbodiedPostureParams, EmbodiedPpcParams

MOVES = ("Ml", "Ms", "Mr")


def triangle_weights(n: int) -> torch.Tensor:
    """Hard-wired PPCc -> PMCm weights ``(3, n*n)`` (eq. 6.10): lower -> Ml, diagonal -> Ms, upper -> Mr."""
    r = torch.arange(n).view(n, 1).expand(n, n)
    c = torch.arange(n).view(1, n).expand(n, n)
    return torch.stack([(r > c), (r == c), (r < c)]).reshape(3, n * n).float()


def check_proprioception(value: str) -> None:
    """Refuse a wrist condition other than :data:`PROPRIOCEPTION`."""
    if value not in PROPRIOCEPTION:
        raise ValueError(f"proprioception must be none, match or mismatch, got {value!r}")


def lca_gain(p, k: float | None = None) -> float:
    """The evidence scale of PMCd: ``p.lca.input_gain``, or when it is None the smallest gain with
    which a full overlap (fraction 1), alone from rest, crosses the threshold within one step of
    ``lca.cycles`` Euler cycles (docs/choices.md): ``threshold k / (1 - (1 - dt k)^cycles)``, for
    the leak ``k`` (default ``lca.k``)."""
    if p.lca.input_gain is not None:
        return float(p.lca.input_gain)
    return full_match_gain(p.lca.threshold, p.lca.k if k is None else k, p.lca.dt, p.lca.cycles)


IDENTICAL_SHARE = 0.9  # rule R1: the share of identical training pairs that decide within one step


def identical_share_gain(pmcd, pairs: torch.Tensor, cycles: int, leak: torch.Tensor) -> torch.Tensor:
    """Rule R1 (docs/choices.md): per participant, the smallest gain with which at
    least ``IDENTICAL_SHARE`` of the identical pairs' evidence ``pairs`` ``(P, N, 2)`` decides (either
    way, for the unit it favours) within ``cycles`` cycles from rest at the leak ``leak`` ``(P,)``,
    or at each of several leaks ``(..., P)`` -> gains of ``leak``'s shape (one search for them all:
    each pair's gain depends on its own evidence and leak alone)."""
    P, N = pairs.shape[:2]
    L = leak.numel() // P
    lk = leak.reshape(L, P, 1).expand(L, P, N).reshape(-1).repeat(2)  # (answer, leak, participant, pair)
    flat = pairs.reshape(1, P * N, 2).expand(2 * L, -1, -1).reshape(-1, 2)
    answer = torch.arange(2).repeat_interleave(L * P * N)
    g = smallest_deciding_gain(pmcd, flat, cycles, answer=answer, leak=lk).view(2, L, P, N)
    need = max(1, math.ceil(IDENTICAL_SHARE * N - 1e-9))
    return torch.minimum(g[0], g[1]).sort(dim=-1).values[..., need - 1].reshape(leak.shape)


def images_of_move(X: ActiveRows, Y: ActiveRows, moves: torch.Tensor, m: int) -> tuple[ActiveRows, ActiveRows]:
    """The training pairs whose randomly drawn movement is ``m``, in their order, per participant
    (padded at the end with empty images, which the delta rule leaves without effect), so each
    forward model sees mini-batches of its own images."""
    keep = moves == m
    return X.select(keep), Y.select(keep)


class RotationEmbodied(nn.Module):
    """The Experiment 4 network for ``P`` participants (``generators``: one per participant;
    ``participant_ids``: who they are, kept for the caller, default ``0..P-1``)."""

    def __init__(self, p, generators: Sequence[torch.Generator], participant_ids: Sequence[int] | None = None) -> None:
        super().__init__()
        self.p = p
        self.participant_ids = list(range(len(generators)) if participant_ids is None else participant_ids)
        n = p.map_size * p.map_size
        self.n, self.size = n, p.map_size
        self.step_angles = (float(p.step_deg), 0.0, -float(p.step_deg))  # Ml, Ms, Mr
        self.fm = nn.ModuleList([
            AllToAll(n, n, init=(0.0, p.init_high), generators=generators, rules=Delta(p.fm.eta), name=f"C{k + 1}")
            for k in range(3)])
        nu = len(p.ppc.angles)
        self.c16, self.c17 = posture_maps(p.init_high, p.posture, n, nu, generators, ("C16", "C17"))
        self.ppc = PopulationMap("PPC", (nu,), 0.0, float(nu - 1), sigma=p.ppc.sigma)
        self.c20 = HardWired(triangle_weights(nu), name="C20")
        self.pmcd = LeakyCompetingAccumulator(2, k=p.lca.k, w=p.lca.w, threshold=p.lca.threshold, dt=p.lca.dt)
        flips = torch.stack([reflection_index(p.map_size, 90.0 + a) for a in p.ppc.angles])
        self.register_buffer("flip_index", flips)  # (units, n) hard-wired C10 per target posture
        P = len(generators)
        # PMCd's input gain per participant (set by calibrate() after training) and the mean evidence of the
        # identical 0-deg training pairs it was fixed on
        self.register_buffer("input_gain", torch.full((P,), lca_gain(p)))
        self.register_buffer("identical_evidence", torch.zeros(P, 2))
        # PMCd's leak per participant (set by calibrate() after training; rule R2 of docs/choices.md)
        self.register_buffer("leak", torch.full((P,), float(p.lca.k)))
        self.fm_sequence: dict | None = None  # the forward models' training sequence (fit_forward_models)

    @property
    def participants(self) -> int:
        return self.c16.participants

    # ------------------------------------------------------------------ learning
    def fit_forward_models(self, X, Y, moves: torch.Tensor, batch: int, progress=None) -> None:
        """C1-C3 by the delta rule (eq. 6.4) in mini-batches of ``batch``: forward model ``m`` on the
        0/1 pairs ``X`` ``(P, N, n)`` -> ``Y`` ``(P, N, n)`` (tensors, or :class:`ActiveRows` of them)
        whose drawn movement ``moves`` ``(P, N)`` is ``m`` (:func:`images_of_move`); ``progress``
        optionally wraps each one's mini-batches. The sequence is kept, compactly, in
        ``fm_sequence`` (what a compact checkpoint stores)."""
        from .sequence_checkpoint import active_units, record

        rows = lambda x: x if isinstance(x, ActiveRows) else ActiveRows(active_units(x), x.shape[-1])  # noqa: E731
        X, Y = rows(X), rows(Y)
        self.train()
        self.fm_sequence = record(X, Y, moves, batch)
        for m, conn in enumerate(self.fm):
            Xm, Ym = images_of_move(X, Y, moves, m)
            conn.learn(Xm, None, sequence=True, batch=batch, target=Ym, progress=progress)

    def fit_posture_maps(self, maps: torch.Tensor, labels: torch.Tensor, generators, progress=None) -> None:
        """C16 and C17 (supervised Kohonen, eq. 6.14-6.16) on edge ``maps`` ``(N, n)`` labelled with
        their wrist-posture units; ``progress`` optionally wraps the list of maps. PMCd is calibrated
        after it (:meth:`calibrate`)."""
        self.train()
        fit_posture_soms([self.c16, self.c17], maps, labels, generators, progress)

    @torch.no_grad()
    def calibrate(self, maps: torch.Tensor, objects: torch.Tensor, mirror: torch.Tensor, angles: torch.Tensor) -> None:
        """Fix PMCd's input gain (``input_gain``) and leak (``leak``), per participant, on the training
        set: edge ``maps`` ``(N, n)`` with the object index, mirror flag and angle of each (how the
        set is built).

        Gain (rule R1 of docs/choices.md): pair every map with itself (target = rotated object,
        0 deg), run the still step and find the smallest gain with which at least 90 % of these
        pairs' (PFCtm, PFCfm) evidence (overlap per target unit) decides within one step. Leak (rule
        R2; :func:`.pmcd_leak.leak_by_rule`): on a grid of 0.05 from w, the smallest k with which at
        most 10 % of the misaligned same-object pairs (object and angle only) decide, their
        still-step evidence held for ``selection.max_steps`` steps (the gain by R1 at each k);
        ``mirror`` is not read. An explicit ``lca.input_gain`` gives the gain instead of R1."""
        P = self.participants
        x = maps.unsqueeze(0).expand(P, -1, -1)
        pairs = self.pair_evidence(x, x)
        self.identical_pairs = pairs  # (P, N, 2): each image against itself (rule R1)
        self.identical_evidence.copy_(pairs.mean(1))
        leak, gain = leak_by_rule(self, x, objects, angles)  # rule R2: object and angle only
        self.leak.copy_(leak)
        self.input_gain.copy_(gain)

    def gain_for(self, leak: torch.Tensor) -> torch.Tensor:
        """PMCd's input gain per participant (rule R1, or ``lca.input_gain``) for the leaks ``leak``
        ``(P,)``, or for several leaks of each ``(..., P)``."""
        p = self.p
        if p.lca.input_gain is not None:
            return torch.full(leak.shape, float(p.lca.input_gain))
        return identical_share_gain(self.pmcd, self.identical_pairs, p.lca.cycles, leak)

    @torch.no_grad()
    def pair_evidence(self, target: torch.Tensor, comparison: torch.Tensor) -> torch.Tensor:
        """The (PFCtm, PFCfm) evidence, per target unit, of the still step of pairs ``(P, B, n)`` -> ``(P, B, 2)``."""
        P, B = comparison.shape[:2]
        pocp = self.forward_step(comparison, torch.ones(P, B, dtype=torch.long))
        t = target.sum(-1).clamp_min(1.0)
        return torch.stack([self.overlap(target, pocp) / t, self.overlap(self.flip_target(target), pocp) / t], -1)

    @torch.no_grad()
    def hold(self, evidence: torch.Tensor, steps: int | None = None, gain: torch.Tensor | None = None,
             leak: torch.Tensor | None = None) -> Decision:
        """PMCd from rest fed the same evidence ``(P, B, 2)`` for ``steps`` steps (default
        ``selection.max_steps``) of ``lca.cycles`` cycles, with each participant's gain and leak
        (default: the calibrated ones) -> a :class:`Decision` of shape ``(P, B)``; ``gain`` and
        ``leak`` of shape ``(..., P)`` (several settings of each participant, run as one batch)
        give one of shape ``(..., P, B)``."""
        p = self.p
        P, B = evidence.shape[:2]
        gain = self.input_gain if gain is None else gain
        leak = self.leak if leak is None else leak
        lead = max(gain.shape[:-1], leak.shape[:-1], key=len)  # (torch.broadcast_shapes imports sympy)
        steps = p.selection.max_steps if steps is None else steps
        ev = gain.unsqueeze(-1).unsqueeze(-1) * evidence  # (..., P, B, 2)
        d = self.pmcd(ev.expand(*lead, P, B, 2).reshape(-1, 2), steps * p.lca.cycles,
                      leak=leak.unsqueeze(-1).expand(*lead, P, B).reshape(-1))
        return Decision(*(v.reshape(*lead, P, B, *v.shape[1:]) for v in (d.winner, d.cycles, d.decided, d.state)))

    def pmcm_input(self, ppcc: torch.Tensor) -> torch.Tensor:
        """PMCm's input AM (eq. 6.10) from PPCc ``(..., units^2)``, scaled by rule R3 (docs/choices.md):
        eq. 6.10 divided by one constant, PPCc's total activity when PPCt and PPCp are the eq. 6.14
        bump on the same most central unit, so that eq. 6.11's input lies in [0, 1] for the bumps and
        keeps eq. 6.10 linear."""
        return self.c20(ppcc) / self.pmcm_full_total()

    def pmcm_full_total(self) -> float:
        """The largest total activity of PPCc (eq. 6.9) with PPCt and PPCp the eq. 6.14 bump on the
        same unit: ``max_j (sum_i bump_j(i))^2`` over the map's units (the most central unit's)."""
        nu = len(self.p.ppc.angles)
        bumps = self.ppc.encode(torch.arange(nu, dtype=torch.float32))  # (nu, nu)
        return float((bumps.sum(-1) ** 2).max())

    def overlap(self, target: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
        """PFCtm (PFCfm) summed: the target units covered by ``image`` read as a population code of
        reach ``match_tolerance`` ``(..., n)`` -> ``(...)``."""
        cover = population_cover(image > 0.5, self.size, self.p.match_tolerance)  # bool: any unit above 0.5 within reach
        return ((target > 0.5) & cover).sum(-1).float()

    def flip_target(self, target: torch.Tensor) -> torch.Tensor:
        """PFCft of targets ``(P, B, n)`` by C10: each reflected about the axis of the orientation PPCt reads."""
        return self.flipped(target, self.posture(self.c17, target))

    def posture(self, som: SOM, x: torch.Tensor) -> torch.Tensor:
        """Winning wrist-posture unit of an image (eq. 6.14: argmax of ``W x``) -> long ``(P, B)``."""
        return som.net(x).argmax(-1)

    def ppcp_code(self, j: torch.Tensor, proprioception: str = "none", uniforms: torch.Tensor | None = None) -> torch.Tensor:
        """PPCp ``(R, units)`` for winners ``j`` ``(R,)``: the eq. 6.14 bump, plus noise
        ``a * (2u - 1)`` for ``uniforms`` u ``(R, units)`` in [0, 1), clipped to [0, 1], plus the wrist
        signal (on unit ``j`` for ``match``, on ``units-1-j`` for ``mismatch``), added before noise
        and clip, so that it saturates at 1 with the bump (one activation per unit, docs/choices.md).
        """
        p, nu = self.p, len(self.p.ppc.angles)
        ppcp = self.ppc.encode(j.float())
        if proprioception != "none":  # one signal, noised and clipped together
            ppcp = ppcp + p.ppc.proprio_gain * self.ppc.encode((j if proprioception == "match" else (nu - 1 - j)).float())
        if uniforms is not None:
            ppcp = ppcp + (2 * uniforms - 1) * p.ppc.noise_amplitude
        return ppcp.clamp(0.0, 1.0)  # PPCp's activity lies in [0, 1]

    def posture_winner(self, score: torch.Tensor, uniforms: torch.Tensor | None) -> torch.Tensor:
        """Winning PPCp unit of the C16 activation potentials ``score`` ``(R, units)`` (eq. 6.14).

        ``posture.tau == 0``: the arg-max, as eq. 6.14 states. ``posture.tau > 0``: the winner is drawn
        from a softmax of the max-normalised potentials at that temperature (the same stochastic
        winner-take-all abstraction as PMCm, eq. 6.11), so an image whose potentials are nearly
        equal (an unfamiliar shape, a "flat" posture code) gives an uncertain winner instead of a
        confident arbitrary one, while a clear orientation still gives the same winner almost always.
        """
        if self.p.posture.tau <= 0 or uniforms is None:
            return score.argmax(-1)
        norm = score / score.max(-1, keepdim=True).values.clamp_min(1e-12)
        return softmax_select(norm, self.p.posture.tau, uniforms=uniforms)

    def forward_step(self, x: torch.Tensor, move: torch.Tensor, active: torch.Tensor | None = None) -> torch.Tensor:
        """POCi -> POCp: the forward model chosen by ``move`` ``(P, B)`` (0 Ml, 1 Ms, 2 Mr).

        A POCl/s/r unit fires when its PMCm unit (1) plus its forward-model input exceeds 1.5,
        i.e. when the prediction exceeds 0.5; only the selected map can fire.
        """
        out = torch.zeros_like(x)
        for m in range(3):
            sel = move == m
            if active is not None:
                sel = sel & active
            if not bool(sel.any()):
                continue
            pred = self.fm[m].net_binary(x * sel.unsqueeze(-1))
            out = torch.where(sel.unsqueeze(-1), (pred + 1.0 > 1.5).float(), out)
        return out

    def flipped(self, target: torch.Tensor, ppct_unit: torch.Tensor) -> torch.Tensor:
        """PFCft: the target reflected about the main axis of the orientation PPCt encodes (C10
        driven by the posture map)."""
        pad = torch.cat([target, torch.zeros(*target.shape[:-1], 1)], dim=-1)
        return torch.gather(pad, -1, self.flip_index[ppct_unit])

    # ------------------------------------------------------------------ trials
    @torch.no_grad()
    def run(self, target: torch.Tensor, rotated: torch.Tensor, generators, proprioception: str = "none",
            noise: bool = False, record=0, flipped: torch.Tensor | None = None) -> dict:
        """Run a batch of trials. ``target``/``rotated``: binary edge maps ``(P, B, n)``.

        ``proprioception``: ``none``, ``match`` (wrist signal on the PPCp unit of the mental
        rotation) or ``mismatch`` (on the opposite unit, ``units-1-j``). ``noise`` adds
        U[-a, a] per PPCp unit and step to the image-derived posture bump and the wrist signal,
        clipped to [0, 1] (both signals share the noise and the [0, 1] ceiling). Randomness (softmax selection, noise,
        time-out answers) comes from ``generators``, one per participant, drawn in a fixed order.
        ``record``: the trials of participant 0 whose maps are returned per step, as a number of
        leading trials or a sequence of trial indices.
        """
        return self.run_conditions(target, rotated, [(proprioception, noise, generators)], record, flipped)[0]

    @torch.no_grad()
    def run_conditions(self, target: torch.Tensor, rotated: torch.Tensor, conditions, record=0,
                       flipped: torch.Tensor | None = None) -> list[dict]:
        """Run the same trials ``(P, B, n)`` under several conditions ``[(proprioception, noise,
        generators), ...]``; returns one result dict per condition (see :meth:`run`), computed as one
        batch (:class:`~neuroimagery.models.rotation_embodied_trials.FusedTrials`)."""
        for prop, _, gens in conditions:
            check_proprioception(prop)
            if len(gens) != target.shape[0]:
                raise ValueError(f"{len(gens)} generators for {target.shape[0]} participants")
        return FusedTrials(self, target, rotated, conditions, record, flipped).run()

    def _snapshot(self, pfct, pfcft, poci, pocp, ppct, ppcp, move, tm, fm, y) -> dict:
        """One step of a sample trial's maps, copied: a view would keep the whole batch's tensor
        of that step alive for the rest of the run."""
        v = lambda x: x.reshape(self.size, self.size).clone()  # noqa: E731
        nu = ppct.shape[-1]
        return {"PFCt": v(pfct), "PFCft": v(pfcft), "POCi": v(poci), "POCp": v(pocp), "PPCt": ppct.clone(),
                "PPCp": torch.zeros(nu), "PPCc": torch.zeros(nu, nu),
                "PMCm": torch.nn.functional.one_hot(move, 3).float(), "PFCtm": v(tm), "PFCfm": v(fm), "PMCd": y.clone()}

    @staticmethod
    def _note_ppc(history, rec, qc, ppcp, ppcc) -> None:
        """Add the wrist maps that chose the next move to the last recorded step of each sample trial
        (``rec``: its (trial, history slot) pairs; the first row of ``qc`` that is the trial)."""
        for i, k in first_rows(qc, rec):
            if history[k]:
                history[k][-1]["PPCp"], history[k][-1]["PPCc"] = ppcp[i].clone(), ppcc[i].clone()
