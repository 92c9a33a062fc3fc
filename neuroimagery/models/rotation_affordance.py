"""Experiment 1 model: mental rotation by affordance and forward-model loops (thesis 5.1, Fig. 5.1).

Maps (thesis sizes):

* ``PC`` 32x32: edge map of the object being rotated (the mental image);
* ``PFC_1`` 32x32: edge map of the target (working memory);
* ``PMC_1`` 31x105: wrist postures. Columns code the wrist angle (-90..90 deg), the rows code
  which of the two objects is held (object A in the upper band, B in the lower), so the map holds
  the thesis's 26 postures (2 objects x 13 orientations) as Gaussian clusters (eq. 4.1);
* ``PFC_2`` 32x64: Kohonen SOM (eq. 4.5) over the concatenated ``[PC, PFC_1]`` (matching);
* ``PMC_2`` 10x20: the answer map, "yes" cluster on the left, "no" cluster on the right.

Connections (all initialised U[0, 0.1]):

* ``C1`` PC -> PMC_1, outstar Hebbian (eq. 4.2-4.3): the affordance, image -> posture cluster;
* ``C2`` PMC_1 -> PC, outstar Hebbian: the forward model, posture of angle ``a`` -> image of
  angle ``a -+ 15`` (one step towards 0), so that repeating C1, C2 rotates the mental image;
* ``C3, C4`` PC, PFC_1 -> PFC_2: the SOM's input weights (4 clusters: AA, AB, BA, BB at 0 deg);
* ``C5`` PFC_2 -> PMC_2, outstar Hebbian: matching cluster -> answer cluster.

Competition: the posture cluster of PMC_1 and the answer of PMC_2 are chosen by a dynamic field
(short-range excitation, long-range inhibition) iterated to threshold; its cycles are the RT
(1 cycle = 1 ms). For PMC_1 the field runs over the wrist-angle axis (the column profile of the
map, 105 units); the object row is then read at the winning column.
"""
from __future__ import annotations

import torch
from torch import nn

from ..nn import SOM, AllToAll, DynamicField, Hebbian, PopulationMap, participant_generators, seeding
from ..nn.functional import intra_op_threads
from ..nn.row_cache import RowCache, distinct_rows
from .factor_checkpoint import FactorCheckpoint, learnt_factors


class AffordanceRotationModel(FactorCheckpoint, nn.Module):
    """Fig. 5.1 for ``participants`` robots with independent initial weights (batched).

    ``e``: its :class:`~.rotation_affordance_params.AffordanceParams`.
    """

    CHECKPOINT_FORMAT = "neuroimagery.exp1.factors/1"  # compact_state (FactorCheckpoint)

    def __init__(self, e, participants: int, seed: int) -> None:
        super().__init__()
        self.e = e
        P = participants
        # rows and columns of PMC_1 both in degrees: row spacing 3 deg, column spacing 180/104 deg
        self.pc = PopulationMap("PC", (32, 32))
        self.pfc1 = PopulationMap("PFC_1", (32, 32))
        self.pmc1 = PopulationMap("PMC_1", (31, 105), low=(-45.0, -90.0), high=(45.0, 90.0), sigma=e.posture_sigma_deg)
        self.pmc2 = PopulationMap("PMC_2", (10, 20), low=(0.0, 0.0), high=(9.0, 19.0), sigma=e.answer_sigma)
        g = lambda s: participant_generators(seed, P, stream=s)  # noqa: E731
        self.c1 = AllToAll(1024, self.pmc1.n, init=(0.0, e.init_high), generators=g(0), rules=Hebbian(e.hebb_eta, "outstar"), name="C1")
        self.c2 = AllToAll(self.pmc1.n, 1024, init=(0.0, e.init_high), generators=g(1), rules=Hebbian(e.hebb_eta, "outstar"), name="C2")
        self.pfc2 = SOM((32, 64), 2048, generators=g(2), init=(0.0, e.init_high), name="PFC_2", **e.som.som_kwargs())
        self.pfc2.rule.cutoff = e.som.cutoff  # truncation of the Gaussian neighbourhood (same for every method)
        self.c5 = AllToAll(2048, self.pmc2.n, init=(0.0, e.init_high), generators=g(3), rules=Hebbian(e.hebb_eta, "outstar"), name="C5")
        self.posture_field = DynamicField((105,), name="PMC_1", **e.field.field_kwargs())
        self.answer_field = DynamicField((10, 20), name="PMC_2", **e.field.field_kwargs())
        self.seed = seed

    @property
    def participants(self) -> int:
        return self.c1.participants

    # ------------------------------------------------------------------ codes
    def object_row(self, obj_index: torch.Tensor) -> torch.Tensor:
        """Row coordinate (deg units) of object 0 (A) or 1 (B) in PMC_1."""
        return torch.where(obj_index == 0, -self.e.object_band_deg, self.e.object_band_deg).float()

    def posture_code(self, obj_index: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
        """Gaussian cluster in PMC_1 for the wrist posture holding ``obj`` at ``angle`` -> ``(..., 3255)``."""
        v = torch.stack([self.object_row(obj_index), angle.float()], -1)
        return self.pmc1.flat(self.pmc1.encode(v))

    def answer_code(self, yes: torch.Tensor) -> torch.Tensor:
        c = torch.where(yes, torch.tensor(4.5), torch.tensor(14.5))
        return self.pmc2.flat(self.pmc2.encode(torch.stack([torch.full_like(c, 4.5), c], -1)))

    def pfc2_activity(self, pc: torch.Tensor, pfc1: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Filtered PFC_2 read-out: a Gaussian cluster around the best-matching unit -> (activity, bmu)."""
        x = torch.cat([pc, pfc1], -1)
        bmu = self.pfc2.bmu(x)  # (P, B)
        d2 = ((self.pfc2.grid[bmu].unsqueeze(-2) - self.pfc2.grid) ** 2).sum(-1)
        return torch.exp(-d2 / (2 * self.e.som.cluster_sigma ** 2)), bmu

    # ------------------------------------------------------------------ training
    @torch.no_grad()
    def fit(self, images: dict[tuple[int, float], torch.Tensor], log=None) -> None:
        """Train C1, C2 (Hebbian, shared sequence), PFC_2 (SOM) and C5 (Hebbian).

        ``images[(obj, angle)]`` is the 1024-vector edge map of object 0/1 at a training angle.
        Patterns are fed object A first, then object B (the thesis's sequential feed).
        """
        e = self.e
        angles = [float(a) for a in range(-90, 91, int(e.step_deg))]
        seq = [(o, a) for o in (0, 1) for a in angles]
        seq = seq * e.hebb_epochs
        obj = torch.tensor([s[0] for s in seq])
        ang = torch.tensor([s[1] for s in seq])
        x = torch.stack([images[s] for s in seq])  # (T, 1024)
        post = self.posture_code(obj, ang)  # (T, 3255)
        nxt = ang - torch.sign(ang) * torch.clamp(ang.abs(), max=e.step_deg)
        nxt_img = torch.stack([images[(int(o), float(a))] for o, a in zip(obj, nxt)])
        self.train()
        self.c1.learn(x, post, sequence=True)  # affordance, online outstar over the shared sequence
        self.c2.learn(post, nxt_img, sequence=True)  # forward model
        # matching SOM on the 4 combinations of upright images, then the answer association
        up = [images[(0, 0.0)], images[(1, 0.0)]]
        pairs = [(i, j) for i in (0, 1) for j in (0, 1)]
        X = torch.stack([torch.cat([up[i], up[j]]) for i, j in pairs])  # (4, 2048)
        P = self.c1.participants
        order = seeding.randint(participant_generators(self.seed, P, stream=4), X.shape[0], (e.som.iterations,))
        with intra_op_threads(e.som.threads, cap=True):  # each SOM step is small: extra threads only add hand-offs
            self.pfc2.fit(X, order=order, method=e.som.method)
        act, _ = self.pfc2_activity(X[:, :1024].expand(P, -1, -1), X[:, 1024:].expand(P, -1, -1))
        yes = torch.tensor([i == j for i, j in pairs])
        target = self.answer_code(yes)  # (4, 200)
        ks = list(range(len(pairs))) * e.hebb_epochs  # the 4 pairs in turn, one per step
        self.c5.learn(act[:, ks], target[ks], sequence=True)
        # what the large weights are formed from, for compact_state (C5 learns step by step and a
        # SOM trained by another method than 'windowed' leaves no factors: saved in full)
        self._factors = learnt_factors(self)
        self.eval()

    # ------------------------------------------------------------------ a trial
    @torch.no_grad()
    def select_posture(self, pc: torch.Tensor | None = None, net: torch.Tensor | None = None):
        """C1 then the competition in PMC_1: winning (row, column), cycles, PMC_1 net input.
        ``net``: C1's net input ``(P, B, 3255)`` of ``pc`` when the caller has it already."""
        s = self.c1.net(pc) if net is None else net  # (P, B, 3255)
        s = s / s.amax(-1, keepdim=True).clamp_min(1e-9)
        grid = s.reshape(*s.shape[:-1], 31, 105)
        prof = grid.amax(-2) ** self.e.sharpen  # wrist-angle profile
        d = self.posture_field(self.e.field.gain * prof, max_cycles=self.e.field.max_cycles)
        col = torch.where(d.decided, d.winner, prof.argmax(-1))
        row = grid.gather(-1, col[..., None, None].expand(*col.shape, 31, 1)).squeeze(-1).argmax(-1)
        return row, col, d.cycles, s

    @torch.no_grad()
    def trial(self, pc0: torch.Tensor, pfc1: torch.Tensor, record: int = 0) -> dict:
        """Rotate the images ``pc0`` ``(P, B, 1024)`` towards upright and answer against ``pfc1``.

        A rotation cycle is C1 (image -> posture cluster, the PMC_1 competition) then, unless the
        cluster is at the centre, C2 (posture -> image one step closer to upright). At most
        ``max_cycles`` cycles, so at most ``max_cycles`` image updates (thesis 5.1.2: "the maximum
        number of rotation cycles is set to 10"); a trial still off centre after them has failed
        to rotate and is matched with its last image.

        Returns ``(P, B)`` tensors: ``steps`` (C2 applications), ``rotated_ok`` (posture cluster at
        the centre within the cycle budget), ``yes``, ``rt`` (competition cycles), and for the first
        ``record`` trials of participant 0 the maps of every cycle (``frames``).
        """
        e = self.e
        P, B, _ = pc0.shape
        pc = pc0.clone()
        steps = torch.zeros(P, B, dtype=torch.long)
        rt = torch.zeros(P, B, dtype=torch.long)
        live = torch.ones(P, B, dtype=torch.bool)
        ok = torch.zeros(P, B, dtype=torch.bool)
        frames = [[] for _ in range(record)]
        # the forward model's image and C1's net input on it depend only on (participant, winning
        # cluster): computed once per distinct winner (RowCache) and looked up
        forward = RowCache(P, self.pmc1.n, self._forward_step)
        net = distinct_rows(self.c1.net, pc)  # C1's net input of the current images
        for _ in range(e.max_cycles):
            row, col, cyc, s = self.select_posture(net=net)
            rt += torch.where(live, cyc, torch.zeros_like(cyc))
            centred = self.pmc1.coords[col, 1].abs() <= e.centre_tolerance_deg
            ok |= live & centred
            if record:
                cluster = self._cluster(row[:1, :record] * 105 + col[:1, :record])
                for k in range(record):
                    frames[k].append({"PC": pc[0, k].reshape(32, 32).clone(), "PMC_1": cluster[0, k].reshape(31, 105).clone()})
            live = live & ~centred
            if not live.any():
                break
            img, img_net = forward(row * 105 + col)  # the forward model: this cycle's image update
            pc = torch.where(live.unsqueeze(-1), img, pc)
            net = torch.where(live.unsqueeze(-1), img_net, net)
            steps += live.long()
        act, bmu = self.pfc2_activity(pc, pfc1)
        a = self.c5.net(act)
        a = a / a.amax(-1, keepdim=True).clamp_min(1e-9)
        d = self.answer_field(self.e.field.gain * self.pmc2.unflat(a), max_cycles=e.field.max_cycles)
        win = torch.where(d.decided, d.winner, a.argmax(-1))
        yes = (win % 20) < 10
        rt += d.cycles
        out = {"steps": steps, "rotated_ok": ok, "yes": yes, "rt": rt, "frames": frames}
        for k in range(record):
            grid = torch.zeros(32 * 64)
            grid[:] = act[0, k]
            frames[k].append({"PC": pc[0, k].reshape(32, 32), "PFC_1": pfc1[0, k].reshape(32, 32),
                              "PFC_2": grid.reshape(32, 64), "PMC_2": d.state[0, k].reshape(10, 20)})
        return out

    def _cluster(self, unit: torch.Tensor) -> torch.Tensor:
        """The PMC_1 posture cluster ``(..., 3255)`` centred on each unit index of ``unit`` (the
        object row's and the wrist column's preferred values)."""
        c = self.pmc1.coords
        return self.pmc1.flat(self.pmc1.encode(torch.stack([c[unit, 0], c[unit, 1]], -1)))

    def _forward_step(self, unit: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """For winning PMC_1 units ``(P, L)``: C2's image of their cluster, max-normalised and
        thresholded (the next mental image), and C1's net input of that image."""
        img = self.c2.net(self._cluster(unit))
        img = img / img.amax(-1, keepdim=True).clamp_min(1e-9)
        img = (img >= self.e.image_threshold).float()
        return img, self.c1.net(img)
