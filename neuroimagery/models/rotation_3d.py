"""Experiment 6 model: search, transform, confirm (after Just & Carpenter, 1976), built from the
maps and connections of the thesis's Experiment 4 network carried into three dimensions.

Stages (docs/exp6.md):

1. **Image** -- a view's surface map (binary voxels) is put into the graded population code
   (:mod:`~neuroimagery.models.voxel_code`); the completion map C_fill (a connection with
   receptive fields along the line of sight, delta rule) fills in the hidden cubes; the result is
   centred on its centre of activity. POCi holds the comparison image, PFCt the target's.
2. **Transform** -- six forward models FM_m (local receptive fields, delta rule on graded dots at
   sub-voxel positions), one per move (+-step about the camera axes x, y, z); PMCm gates them.
3. **Search** -- the rotation still required is estimated from a correspondence between the two
   images: each image's principal axes, learnt by Sanger's rule in a fast 3x3 connection (C_axes),
   are matched, each proper sign combination is refined locally by a coarse comparison of the two
   images, and the best is chosen. PPCt holds the estimate; PPCp the net turn, composed from each
   step's efference copy. Each move unit is driven by how close to identity the remaining rotation
   (PPCt composed with the inverse of PPCp) would be after its move; the most active wins and
   "still" ends the transform. The wrist signal of the proprioception conditions joins PPCp_z.
4. **Confirm** -- once the transform stops, PMCd (leaky competing accumulator, eq. 6.12-6.13)
   takes YES evidence from the cosine of the turned image with the target and NO evidence from
   the largest cluster of mismatching voxels, in cubes; the cut between the two is fixed on the
   training objects (:meth:`Rotation3D.fit_confirm`).

``strategy='parity'`` (an ablation) skips the transform: the handedness of the matched principal
axes (the best of all eight sign combinations proper or not) decides at once.
"""
from __future__ import annotations

import math
from typing import Sequence

import torch
from torch import nn

from ..nn import Delta, LeakyCompetingAccumulator, PopulationMap, Sanger
from ..nn.connections import Connection
from ..nn.decision import full_match_gain
from ..nn.local import LocalConnection
from . import voxel_code as vc
from .layout_3d import (AXES, MOVES, SIGNS, WRIST_AXIS, fill_offsets, fm_bytes,  # noqa: F401 (re-exported)
                        grid_for_budget, matched_axes, move_angles, receptive_radius)
from .recording import sample_indices
from .rotation_embodied import check_proprioception

MATCH_CHUNK = 8  # rows of the coarse comparison formed together (speed only)
COARSE_UNITS = 128  # blocks of a coarse image the search compares (the most active ones)


class Rotation3D(nn.Module):
    """The Experiment 6 network for ``P`` participants (``generators``: one per participant).

    ``p``: the experiment config (groups ``image``, ``fm``, ``search``, ``ppc``, ``selection``,
    ``lca``, ``confirm`` and the top-level ``step_deg``, ``strategy``); ``cube_voxels``: voxels per cube edge (the unit of the mismatch cluster)."""

    def __init__(self, p, side: int, generators: Sequence[torch.Generator], cube_voxels: float) -> None:
        super().__init__()
        self.p, self.side, self.n = p, int(side), int(side) ** 3
        self.cube_voxels = float(cube_voxels)
        self.radius = receptive_radius(side, p.step_deg)
        self.moves = move_angles(float(p.step_deg))
        # the rotation of each PMCm unit's move (moves, 3, 3) (still: identity)
        self.move_turns = torch.stack([torch.eye(3, dtype=torch.float64)] + [vc.axis_rotation(a, d) for a, d in self.moves[1:]])
        init = (0.0, p.init_high)
        self.fill = LocalConnection(side, 0, generators, init=init, rules=Delta(p.image.eta), name="C_fill",
                                    offset_set=fill_offsets(p.image.fill_depth, p.image.lateral))
        self.fm = nn.ModuleList([LocalConnection(side, self.radius, generators, init=init, rules=Delta(p.fm.eta),
                                                 name=f"FM_{m}") for m in MOVES[1:]])
        # initial weights of the fast principal-axes connection, one draw per participant
        self.register_buffer("axes_init", torch.stack([torch.linalg.qr(torch.randn(3, 3, generator=g, dtype=torch.float64))[0]
                                                       for g in generators]))
        nu = int(round(360.0 / p.step_deg)) + 1  # units every step from -180 to 180 deg
        self.ppc = PopulationMap("PPC", (nu,), -180.0, 180.0, sigma=p.ppc.sigma * 360.0 / (nu - 1))
        self.pmcd = LeakyCompetingAccumulator(2, k=p.lca.k, w=p.lca.w, threshold=p.lca.threshold, dt=p.lca.dt)
        P = len(generators)
        self.register_buffer("cut", torch.full((P,), float("nan")))  # cubes: the mismatch cluster's cut (fit_confirm)
        self.register_buffer("match_ref", torch.full((P,), float("nan")))  # the training same pairs' mean match

    @property
    def participants(self) -> int:
        return self.fm[0].participants

    def describe(self) -> dict:
        """Sizes of the network (for the report)."""
        return {"side": self.side, "receptive_radius": self.radius, "offsets": self.fm[0].K, "moves": len(self.fm),
                "cube_voxels": round(self.cube_voxels, 4), "fill_offsets": self.fill.K,
                "fm_mb_per_participant": round(sum(c.weights_per_participant for c in self.fm) * 4 / 1e6, 2)}

    # ------------------------------------------------------------------ stage 1: the image
    def encode(self, occ: torch.Tensor) -> torch.Tensor:
        """The graded population code of binary surface maps ``(..., n)``."""
        return vc.graded(occ, self.side, self.p.image.sigma)

    def complete(self, code: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """C_fill on graded rows ``(R, n)``: the hidden parts filled in (activity cut to [0, 1])."""
        if self.p.image.fill_depth < 0:
            return code
        return self.fill.net_rows(code, part).clamp(0.0, 1.0)

    def image(self, occ: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """Surface maps ``(R, n)`` -> the model's image: coded, completed, centred."""
        return vc.recentre(self.complete(self.encode(occ), part), self.side)

    @torch.no_grad()
    def fit_completion(self, surface: torch.Tensor, whole: torch.Tensor, batch: int) -> None:
        """Delta rule of C_fill: graded surface codes ``(P, N, n)`` -> graded whole-volume codes."""
        for s in range(0, surface.shape[1], batch):
            self.fill.learn(pre=surface[:, s:s + batch], target=whole[:, s:s + batch])

    # ------------------------------------------------------------------ stage 2: the transform
    def step(self, x: torch.Tensor, move: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """One move per row of images ``(R, n)`` (0 = still: unchanged), activity cut to [0, 1]."""
        out = x.clone()
        for m, conn in enumerate(self.fm):
            sel = (move == m + 1).nonzero().squeeze(-1)
            if sel.numel():
                out[sel] = conn.net_rows(x[sel], part[sel]).clamp(0.0, 1.0)
        return out

    @torch.no_grad()
    def forward_error(self, move: int, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """Squared error of forward model ``move`` on a batch, summed over voxels, mean over images."""
        return (self.fm[move - 1].net(x) - y).pow(2).sum(-1).mean()

    def forward_curve(self, move: int) -> str:
        """The tag of forward model ``move``'s training curve (:mod:`neuroimagery.nn.monitor`)."""
        return f"train/{self.fm[move - 1].name}/squared_error"

    @torch.no_grad()
    def fit_forward_models(self, move: int, x: torch.Tensor, y: torch.Tensor) -> None:
        """Delta rule (eq. 6.4) of forward model ``move`` (1..6, :data:`MOVES`) on one batch of
        graded images ``x`` ``(P, B, n)`` and their turned versions ``y``."""
        self.fm[move - 1].learn(pre=x, target=y)

    # ------------------------------------------------------------------ stage 3: the search
    def principal_axes(self, maps: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """Principal axes ``(R, 3, 3)`` (rows, by decreasing spread) of images ``(R, n)``, learnt by
        Sanger's rule in a fast 3x3 connection from the images' active voxel positions. The batch
        update over all voxels (weighted by activity) equals the update over the three columns of
        the Cholesky factor of their second moments, which the hook is given to save work."""
        C = vc.second_moment(maps.double(), self.side)
        L = torch.linalg.cholesky(C + 1e-9 * torch.eye(3, dtype=C.dtype))
        samples = (L * math.sqrt(3.0)).transpose(1, 2)  # (R, 3, 3): sum_b x_b x_b^T / 3 = C
        conn = Connection(3, 3, self.axes_init[part].clone(), rules=Sanger(self.p.search.eta), name="C_axes")
        conn.train()
        for _ in range(self.p.search.iterations):
            conn.learn(samples)
        basis = torch.eye(3, dtype=samples.dtype).expand(samples.shape[0], 3, 3)
        W = conn.net(basis).transpose(1, 2)  # the learnt rows: the connection's response to each input axis
        return W / W.norm(dim=-1, keepdim=True).clamp_min(1e-12)

    def coarse_points(self, maps: torch.Tensor):
        """A coarse code of images: activity pooled over blocks of ``search.coarse`` voxels,
        as (positions ``(c, 3)``, weights ``(R, c)``)."""
        k, side = self.p.search.coarse, self.side
        v = maps.double().reshape(-1, 1, side, side, side)
        pooled = torch.nn.functional.avg_pool3d(v, k, stride=k, ceil_mode=True)
        m = pooled.shape[-1]
        cz = (torch.arange(m, dtype=torch.float64) * k + (min(k, side) - 1) / 2.0) - (side - 1) / 2.0
        z, y, x = torch.meshgrid(cz, cz, cz, indexing="ij")
        pos = torch.stack([x.reshape(-1), y.reshape(-1), z.reshape(-1)], -1)
        return pos, pooled.reshape(maps.shape[0], -1)

    def coarse_code(self, maps: torch.Tensor):
        """The coarse code the search compares: each image's :data:`COARSE_UNITS` most active blocks
        of ``search.coarse`` voxels, as (positions ``(rows, k, 3)``, weights ``(rows, k)``)."""
        pos, w = self.coarse_points(maps)
        w, i = w.topk(min(COARSE_UNITS, w.shape[1]), -1)
        return pos[i], w

    def coarse_match(self, target, comp, R: torch.Tensor) -> torch.Tensor:
        """Coarse comparison ``(rows,)``: overlap of the coarse target with the coarse comparison
        image whose positions are turned by ``R`` ``(rows, 3, 3)`` (Gaussian of one cube edge).
        ``target``, ``comp``: images ``(rows, n)`` or their :meth:`coarse_code`."""
        (pt, wt), (pc, wc) = [x if isinstance(x, tuple) else self.coarse_code(x) for x in (target, comp)]
        turned = torch.einsum("rij,rcj->rci", R, pc)
        st, sc = (pt * pt).sum(-1), (turned * turned).sum(-1)
        out = torch.empty(R.shape[0], dtype=torch.float64)
        for a in range(0, R.shape[0], MATCH_CHUNK):  # a few rows at a time: (rows, k_t, k_c) stays in the cache
            b = min(a + MATCH_CHUNK, R.shape[0])
            d2 = torch.baddbmm(st[a:b].unsqueeze(2) + sc[a:b].unsqueeze(1), pt[a:b], turned[a:b].transpose(1, 2),
                               alpha=-2.0)  # squared distances
            g = d2.clamp_min_(0.0).div_(-2.0 * self.cube_voxels ** 2).exp_()
            out[a:b] = torch.bmm(torch.bmm(wt[a:b].unsqueeze(1), g), wc[a:b].unsqueeze(2)).view(-1)
        return out

    def refine(self, target, comp, R: torch.Tensor, score: torch.Tensor, scales: Sequence[float] | None = None):
        """Local refinement of candidate rotations ``R`` ``(rows, 3, 3)`` by the same coarse comparison:
        at each scale of ``scales`` (deg; default ``search.refine``) the candidate turns by that angle
        about each camera axis either way while that raises the match (at most ``search.refine_steps``
        times). Returns (refined rotations, their match)."""
        scales = list(self.p.search.refine if scales is None else scales)
        small = {d: torch.stack([vc.axis_rotation(a, sg * d) for a in AXES for sg in (-1.0, 1.0)]) for d in scales}
        codes = [x if isinstance(x, tuple) else self.coarse_code(x) for x in (target, comp)]
        R, score = R.clone(), score.clone()
        m = 2 * len(AXES)
        for d in scales:
            # a row whose match did not rise keeps its rotation, so its candidates would not raise it at
            # the next step either: each step compares only the rows that rose at the one before
            act = torch.arange(R.shape[0])
            for _ in range(self.p.search.refine_steps):
                if act.numel() == 0:
                    break
                cand = small[d].unsqueeze(0) @ R[act].unsqueeze(1)  # (rows, 6, 3, 3)
                sub = [tuple(v[act].repeat_interleave(m, 0) for v in c) for c in codes]  # each row once per move
                sc = self.coarse_match(*sub, cand.reshape(-1, 3, 3)).view(-1, m)
                r = torch.arange(act.numel())
                best = sc.argmax(-1)
                up = sc[r, best] > score[act]
                R[act[up]] = cand[r[up], best[up]]
                score[act[up]] = sc[r[up], best[up]]
                act = act[up]
        return R, score

    def search(self, target: torch.Tensor, comp: torch.Tensor, part: torch.Tensor, proper: bool = True):
        """The rotation still required ``(R, 3, 3)`` (turns the comparison image onto the target)
        and whether the best correspondence was proper (a rotation) or improper (a reflection).
        Each sign combination of the matched principal axes is refined locally (:meth:`refine`)
        before the best is chosen."""
        E = self.principal_axes(torch.cat([target, comp]), torch.cat([part, part]))  # both images' rows at once
        Et, Ec = E[:target.shape[0]], E[target.shape[0]:]
        ct, cc = self.coarse_code(target), self.coarse_code(comp)
        cands, dets, scores = [], [], []
        for s in SIGNS:
            R = matched_axes(Et, Ec, s)
            det = torch.linalg.det(R)
            sc = self.coarse_match(ct, cc, R)
            k = (det > 0).nonzero().squeeze(-1) if proper else torch.arange(R.shape[0])  # reflections only if they may win
            if k.numel() and self.p.search.refine:
                R, sc = R.clone(), sc.clone()
                R[k], sc[k] = self.refine(tuple(x[k] for x in ct), tuple(x[k] for x in cc), R[k], sc[k])
            cands.append(R)
            dets.append(det)
            scores.append(sc)
        scores = torch.stack(scores, -1)  # (rows, 8)
        det = torch.stack(dets, -1)
        if proper:
            scores = torch.where(det > 0, scores, torch.full_like(scores, -math.inf))
        best = scores.argmax(-1)
        Rb = torch.stack(cands, 1)[torch.arange(target.shape[0]), best]
        return Rb, det[torch.arange(target.shape[0]), best] > 0

    def ppc_code(self, vec: torch.Tensor, proprioception: str = "none", wrist: torch.Tensor | None = None) -> torch.Tensor:
        """Population codes ``(R, 3, nu)`` of rotation vectors ``(R, 3)`` (deg per camera axis), plus
        the wrist signal on the line-of-sight axis: ``match`` a bump on the wrist's relative
        rotation ``wrist`` (the turn done so far), ``mismatch`` on its opposite; summed, cut to
        [0, 1] (as Exp 4's PPCp)."""
        check_proprioception(proprioception)
        code = self.ppc.encode(vec.float().clamp(-180.0, 180.0).unsqueeze(-1)).reshape(vec.shape[0], 3, -1)
        if proprioception == "none":
            return code
        a = AXES.index(WRIST_AXIS)
        w = wrist if proprioception == "match" else -wrist
        bump = self.ppc.encode(w.float().clamp(-180.0, 180.0).unsqueeze(-1)).reshape(vec.shape[0], -1)
        code[:, a] = (code[:, a] + self.p.ppc.proprio_gain * bump).clamp(0.0, 1.0)
        return code

    # ------------------------------------------------------------------ stage 4: confirm
    def mismatch(self, turned: torch.Tensor, target: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(match: cosine of the turned image with the target, largest mismatch cluster in cubes): a
        voxel mismatches when one image is above ``confirm.level`` there and the other is not, and the
        largest 26-connected cluster of the mismatching voxels is counted in cubes."""
        lv = self.p.confirm.level
        vox = vc.largest_cluster(((turned > lv) != (target > lv)).float(), self.side)
        return vc.cosine(turned, target), vox.double() / self.cube_voxels ** 3

    @torch.no_grad()
    def fit_confirm(self, cubes: torch.Tensor, match: torch.Tensor, same: torch.Tensor) -> None:
        """The rule fixing the cut on the training objects' pairs after alignment (per participant):
        ``cubes``, ``match`` ``(P, N)`` measured by :meth:`align`; ``same`` ``(N,)`` whether each pair
        shows the same object. The cut is the one that puts most pairs on their side (the midpoint
        of the widest such interval); the reference match is the same pairs' mean match."""
        for k in range(cubes.shape[0]):
            c = cubes[k].double()
            vals = torch.unique(c)
            edges = torch.cat([vals[:1] - 1.0, (vals[1:] + vals[:-1]) / 2, vals[-1:] + 1.0])
            acc = torch.stack([((c > e) == ~same).double().mean() for e in edges])
            best = torch.nonzero(acc == acc.max()).squeeze(-1)
            self.cut[k] = float(edges[best].median()) if len(best) % 2 else float(edges[best[len(best) // 2 - 1: len(best) // 2 + 1]].mean())
            self.match_ref[k] = float(match[k][same].double().mean())

    def evidence(self, match: torch.Tensor, cubes: torch.Tensor, part: torch.Tensor) -> torch.Tensor:
        """PMCd input ``(R, 2)``: YES = gain x match, NO = gain x reference match x cluster / cut."""
        gain = lca_gain(self.p.lca)
        no = self.match_ref[part].double() * cubes / self.cut[part].double().clamp_min(1e-6)
        return (gain * torch.stack([match.double(), no], -1)).float()

    # ------------------------------------------------------------------ trials
    def composed_move(self, required: torch.Tensor, net: torch.Tensor, proprioception: str = "none") -> torch.Tensor:
        """PMCm move per row: the rotation still required is the search's
        estimate ``required`` composed with the inverse of the net turn ``net`` made so far (both
        ``(R, 3, 3)``, the net turn composed from the steps' efference copies, PPCp); each move unit is
        driven by how close to identity that remaining rotation would be after its move (minus its
        geodesic angle, in steps; "still": the angle now); the most active unit wins, "still" unless a
        move brings the remaining rotation closer to identity. The wrist signal joins PPCp_z as in
        :meth:`ppc_code`; it shifts the sensed
        turn about the line of sight by what it moves that population's read-out."""
        sensed = net
        if proprioception != "none":
            vz = vc.rotation_vector(net)[:, AXES.index(WRIST_AXIS)]
            z = torch.zeros(net.shape[0], 3, dtype=torch.float64)
            z[:, AXES.index(WRIST_AXIS)] = vz
            plain = self.ppc.decode(self.ppc_code(z)[:, AXES.index(WRIST_AXIS)])
            felt = self.ppc.decode(self.ppc_code(z, proprioception, vz)[:, AXES.index(WRIST_AXIS)])
            deg, row = torch.unique((felt - plain).double(), return_inverse=True)  # few distinct shifts
            shift = torch.stack([vc.axis_rotation(WRIST_AXIS, float(d)) for d in deg])[row]
            sensed = shift @ net
        remaining = required @ sensed.transpose(1, 2)
        turns = self.move_turns.to(remaining.dtype)
        after = remaining.unsqueeze(1) @ turns.transpose(1, 2).unsqueeze(0)  # (R, moves, 3, 3): still first
        ang = vc.axis_angle(after.reshape(-1, 3, 3))[1].reshape(after.shape[0], -1)
        am = (-ang / self.p.step_deg).float()
        return am.argmax(-1)  # the first of equals: "still" unless a move brings the remaining rotation closer

    @torch.no_grad()
    def align(self, target: torch.Tensor, comp: torch.Tensor, generators, record: int | Sequence[int] = 0,
              proprioception: str = "none") -> dict:
        """Search and transform for images ``(P, B, n)`` (already coded, completed and centred):
        the turned comparison images, steps, the net turn (``net``, composed from the steps'
        efference copies in their order; ``done``, its rotation vector), the required rotation, history.
        Each move is chosen from the remaining rotation (:meth:`composed_move`)."""
        p = self.p
        P, B, n = target.shape
        if len(generators) != P:
            raise ValueError(f"{len(generators)} generators for {P} participants")
        Q = P * B
        part = torch.arange(P).repeat_interleave(B)
        pfct, poci = target.reshape(Q, n), comp.reshape(Q, n)
        required, proper = self.search(pfct, poci, part, proper=p.strategy != "parity")
        steps = torch.zeros(Q, dtype=torch.long)
        live = torch.ones(Q, dtype=torch.bool) if p.strategy == "rotate" else torch.zeros(Q, dtype=torch.bool)
        rec = sample_indices(record, B)
        hist: list[list[dict]] = [[] for _ in rec]
        img = poci.clone()
        turn = self.move_turns
        net = torch.eye(3, dtype=torch.float64).repeat(Q, 1, 1)
        for s in range(p.selection.max_steps):
            for g in generators:  # each step takes one (B,) draw of every stream: run()'s tie coin follows the steps' draws
                torch.rand(B, generator=g)
            q = live.nonzero().squeeze(-1)
            if q.numel() == 0:
                break
            move = self.composed_move(required[q], net[q], proprioception)
            img[q] = self.step(img[q], move, part[q])
            net[q] = turn[move] @ net[q]  # the efference copy of each step, composed in order
            moving = move > 0
            steps[q] += moving.long()
            live[q] = moving
            for h, k in zip(hist, rec):
                if bool(live[k]) or bool((q == k).any()):
                    h.append({"PFCt": pfct[k].clone(), "POCp": img[k].clone(),
                                    "PMCm": torch.nn.functional.one_hot(move[(q == k).nonzero()[0, 0]] if (q == k).any()
                                                                        else torch.tensor(0), len(MOVES)).float()})
        done = vc.rotation_vector(net)
        return {"turned": img, "steps": steps, "done": done, "net": net, "required": required, "proper": proper,
                "timeout": live, "history": hist, "part": part, "target": pfct}

    @torch.no_grad()
    def run(self, target: torch.Tensor, comp: torch.Tensor, generators, record: int | Sequence[int] = 0,
            proprioception: str = "none") -> dict:
        """Trials ``(P, B, n)`` of images (coded, completed, centred). Randomness from ``generators``
        (one ``(B,)`` draw per step and one for a tie, in a fixed order, so a result does not depend
        on the batch). RT = accumulator cycles: ``lca.cycles`` for the search, as many per step,
        then the cycles PMCd takes to decide (at most ``lca.cycles * selection.max_steps``)."""
        p = self.p
        check_proprioception(proprioception)
        if torch.isnan(self.cut).any():
            raise RuntimeError("Rotation3D.run: the confirm stage is not fitted (fit_confirm)")
        P, B, n = target.shape
        out = self.align(target, comp, generators, record, proprioception)
        part = out["part"]
        match, cubes = self.mismatch(out["turned"], out["target"])
        ev = self.evidence(match, cubes, part)
        if p.strategy == "parity":  # the handedness of the matched axes decides: a reflection is NO evidence
            ev = torch.where(out["proper"].unsqueeze(-1), ev[:, :1].expand(-1, 2) * torch.tensor([1.0, 0.0]),
                             ev[:, :1].expand(-1, 2) * torch.tensor([0.0, 1.0]))
        dec = self.pmcd(ev, p.lca.cycles * p.selection.max_steps, state=self.pmcd.initial_state((P * B,)))
        coin = torch.stack([torch.rand(B, generator=g) for g in generators]).reshape(P * B)
        answer = torch.where(dec.decided, dec.winner, (coin < 0.5).long())
        rt = p.lca.cycles * (1 + out["steps"]) + dec.cycles
        for k, h in zip(sample_indices(record, B), out["history"]):
            if h:
                h[-1].update({"PMCd": dec.state[k].clone(), "match": match[k].float(), "cubes": cubes[k].float()})
        sh = (P, B)
        return {"answer": answer.reshape(sh), "rt": rt.reshape(sh), "rotation_steps": out["steps"].reshape(sh),
                "decided": dec.decided.reshape(sh), "turned": out["done"].reshape(P, B, 3).float(),
                "required": out["required"].reshape(P, B, 3, 3), "match": match.reshape(sh).float(),
                "cubes": cubes.reshape(sh).float(), "history": out["history"]}


def lca_gain(g) -> float:
    """The evidence scale of PMCd (Exp 4's rule): ``g.input_gain``, or when it is None the smallest
    gain with which a full match (1), alone from rest, crosses the threshold within ``g.cycles``
    Euler cycles: ``threshold k / (1 - (1 - dt k)^cycles)``."""
    if g.input_gain is not None:
        return float(g.input_gain)
    return full_match_gain(g.threshold, g.k, g.dt, g.cycles)
