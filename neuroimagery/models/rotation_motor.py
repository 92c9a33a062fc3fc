"""Experiment 2 model: mental rotation through inverse and forward motor models with wrist
proprioception (thesis 5.2, Fig. 5.6, Table 5.1).

Maps (thesis sizes): ``PP`` 32x32 (mental image), ``PFC_1`` 32x32 (target), ``SS`` 31x100 (wrist
proprioception: columns = wrist angle -90..90, rows = the held object, A upper band / B lower),
``PMC_1`` 31x100 (desired wrist posture, one central band), ``PMC_2`` 10x20 (answer), ``PFC_2``
64x64 SOM over ``[PP, PFC_1]``, ``M1_1`` 64x64 SOM over ``[SS, PMC_1]`` (6,200 inputs), ``M1_2``
10x30 with clusters N1 (30 deg clockwise), N2 (stay), N3 (30 deg counter-clockwise).

Connections: C1 PP->PMC_1 (pre-activates the 7 postures at 0.2), C6 PFC_1->PMC_1 (selects one at
1.0), C7/C8 -> M1_1 (SOM), C9 M1_1->M1_2, C10 M1_1->SS (forward model), C2 SS->PP (image of the
predicted posture), C3/C4 -> PFC_2 (SOM), C5 PFC_2->PMC_2; every Hebbian one is outstar Oja
(eq. 4.2-4.3), initial weights U[0, 0.1]. Training cycles follow Table 5.1 for C1, C6, C5, C9,
C10 and the two SOMs. Two departures from the thesis: C2 (Table 5.1: 14 patterns, 84 cycles) is
trained on the same first ``hebb_steps`` (1,960) babbling steps as C9 and C10, as the pairs (next
SS posture, its image); and C9, C10 and C2 learn after the SOM M1_1 has finished all its steps
(C9 and C10 from the clusters of the trained map), whereas the babbling procedure (e)-(g) of
5.2.1 D trains them at the end of each babbling step alongside the SOM.

The competition inside SS (forward prediction + weaker proprioception, which also pre-activates
the field) and inside PMC_2 is a dynamic field run to threshold; the SS field runs along the
wrist-angle axis (100 units). The SOMs train by the batched windowed form of the online rule
(``SOM.fit(method='windowed')``) unless ``som.method`` says otherwise. RT =
SS competition cycles over the rotation steps + PMC_2 cycles (1 cycle = 1 ms).
"""
from __future__ import annotations

from types import SimpleNamespace

import torch
from torch import nn

from ..nn.learning import IndexedRows
from ..nn.row_cache import RowCache, distinct_rows
from ..nn.som import fit_together
from ..nn import SOM, seeding, AllToAll, DynamicField, Hebbian, PopulationMap, participant_generators
from ..nn.functional import intra_op_threads
from .factor_checkpoint import FactorCheckpoint, learnt_factors

ANGLES = [-90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0]
CHECKPOINT_FORMAT = "neuroimagery.exp2.factors/1"  # the compact checkpoint of MotorRotationModel.compact_state
SS_ROWS, SS_COLS = 31, 100  # the SS (and PMC_1) grid: rows = the held object, columns = wrist angle -90..90 deg
SS_UNITS = SS_ROWS * SS_COLS  # 3100
PP_SIDE, M1_SIDE = 32, 64  # PP / PFC_1 maps 32 x 32; M1_1 / PFC_2 maps 64 x 64 (Table 5.1)
PP_UNITS, M1_UNITS = PP_SIDE * PP_SIDE, M1_SIDE * M1_SIDE  # 1024, 4096
OBJECT_B_ROW = 15  # SS rows from this one on are object B's band
ROTATED_WITHIN_DEG = 15.0  # a rotation reached the desired posture when it ends within this (deg)
PEAK_FLOOR = 1e-9  # smallest peak an activity is divided by when scaled to a peak of 1


class MotorRotationModel(FactorCheckpoint, nn.Module):
    """Fig. 5.6 for ``participants`` robots (batched); ``e``: its :class:`~.rotation_motor_params.MotorRotationParams`."""

    CHECKPOINT_FORMAT = CHECKPOINT_FORMAT

    def __init__(self, e, participants: int, seed: int) -> None:
        super().__init__()
        self.e, self.seed = e, seed
        P = participants
        g = lambda s: participant_generators(seed, P, stream=s)  # noqa: E731
        lo, hi = (-45.0, -90.0), (45.0, 90.0)
        self.ss = PopulationMap("SS", (31, 100), lo, hi, sigma=e.posture_sigma_deg)
        self.pmc1 = PopulationMap("PMC_1", (31, 100), lo, hi, sigma=e.posture_sigma_deg)
        self.pmc2 = PopulationMap("PMC_2", (10, 20), (0.0, 0.0), (9.0, 19.0), sigma=e.answer_sigma)
        self.m12 = PopulationMap("M1_2", (10, 30), (0.0, 0.0), (9.0, 29.0), sigma=e.answer_sigma)
        h = Hebbian(e.hebb_eta, "outstar")
        init = (0.0, e.init_high)
        self.c1 = AllToAll(PP_UNITS, SS_UNITS, init=init, generators=g(0), rules=h, name="C1")
        self.c6 = AllToAll(PP_UNITS, SS_UNITS, init=init, generators=g(1), rules=h, name="C6")
        self.c2 = AllToAll(SS_UNITS, PP_UNITS, init=init, generators=g(2), rules=h, name="C2")
        self.c9 = AllToAll(M1_UNITS, 300, init=init, generators=g(3), rules=h, name="C9")
        self.c10 = AllToAll(M1_UNITS, SS_UNITS, init=init, generators=g(4), rules=h, name="C10")
        self.c5 = AllToAll(M1_UNITS, 200, init=init, generators=g(5), rules=h, name="C5")
        som = dict(init=init, **e.som.som_kwargs())
        self.m11 = SOM((M1_SIDE, M1_SIDE), 2 * SS_UNITS, generators=g(6), name="M1_1", **som)
        self.pfc2 = SOM((M1_SIDE, M1_SIDE), 2 * PP_UNITS, generators=g(7), name="PFC_2", **som)
        for s_ in (self.m11, self.pfc2):
            s_.rule.cutoff = e.som.cutoff  # truncation of the Gaussian neighbourhood (same for every method)
        fk = e.field.field_kwargs()
        self.ss_field = DynamicField((100,), name="SS", **fk)
        self.answer_field = DynamicField((10, 20), name="PMC_2", **fk)

    @property
    def participants(self) -> int:
        return self.c1.participants

    # ------------------------------------------------------------------ codes
    def ss_code(self, obj: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
        row = torch.where(obj == 0, -self.e.object_band_deg, self.e.object_band_deg).float()
        return self.ss.flat(self.ss.encode(torch.stack([row, angle.float()], -1)))

    def pmc1_code(self, angle: torch.Tensor, amplitude: float = 1.0) -> torch.Tensor:
        v = torch.stack([torch.zeros_like(angle, dtype=torch.float32), angle.float()], -1)
        return self.pmc1.flat(self.pmc1.encode(v, amplitude))

    def cluster(self, shape_grid: torch.Tensor, centre_col: torch.Tensor) -> torch.Tensor:
        return self.m12.flat(self.m12.encode(torch.stack([torch.full_like(centre_col, 4.5), centre_col], -1)))

    def som_bump(self, som: SOM, x: torch.Tensor | None = None, bmu: torch.Tensor | None = None) -> torch.Tensor:
        """The winning cluster of a SOM: a truncated Gaussian around the best-matching unit of ``x``
        (or around the given ``bmu``)."""
        bmu = som.bmu(x) if bmu is None else bmu
        d2 = ((som.grid[bmu].unsqueeze(-2) - som.grid) ** 2).sum(-1)
        b = torch.exp(-d2 / (2 * self.e.som.cluster_sigma ** 2))
        return torch.where(b < 1e-3, torch.zeros_like(b), b)

    @torch.no_grad()
    def m11_table(self, obj: torch.Tensor, angle: torch.Tensor):
        """M1_1's best-matching unit for (SS code, PMC_1 code) pairs, by a table.

        Its input is always an SS code from the finite set ``(obj, angle)`` given here and one of
        the 7 desired-posture codes, so ``|w|^2 - 2 w.x + |x|^2`` splits into per-half dot products
        computed once (``K + 7`` codes instead of one 6,200-input product per query). Returns
        ``bmu(ss_index, des_index)`` -> ``(P, ...)``, the same units as ``SOM.bmu`` on the
        concatenated input (up to float rounding).
        """
        ss = self.ss_code(obj, angle)  # (K, 3100)
        pm = self.pmc1_code(torch.tensor(ANGLES))  # (7, 3100)
        A = self.m11.part_products(ss, 0, SS_UNITS)  # (P, K, U)
        Bm = self.m11.part_products(pm, SS_UNITS)  # (P, 7, U)
        nrm = self.m11.prototype_norms().unsqueeze(1)  # (P, 1, U)
        ns, npm = (ss * ss).sum(-1), (pm * pm).sum(-1)
        P, n_pm = self.m11.participants, pm.shape[0]
        pi = torch.arange(P)

        def winners(key: torch.Tensor) -> tuple[torch.Tensor]:  # key (P, L) = ss_index * 7 + des_index
            si, di = key // n_pm, key % n_pm
            d = nrm - 2 * (A[pi[:, None], si] + Bm[pi[:, None], di]) + (ns[si] + npm[di]).unsqueeze(-1)
            return (d.argmin(-1),)

        # each (participant, SS code, desired posture) is searched once: a row's distances and its
        # argmin are elementwise, the same numbers in any batch
        cache = RowCache(P, ss.shape[0] * n_pm, winners)

        def bmu(si: torch.Tensor, di: torch.Tensor) -> torch.Tensor:
            shp = si.shape
            (b,) = cache((si * n_pm + di).reshape(P, -1))
            return b.reshape(shp)

        return bmu

    # ------------------------------------------------------------------ training
    @torch.no_grad()
    def fit_soms(self, jobs) -> list[torch.Tensor]:
        """Online Kohonen training of SOMs, ``jobs`` = ``[(som, X, order (P, T), parts)]``, by
        ``e.som.method``.

        All three methods run the same online rule and return the same winners; they differ in
        cost only (``windowed`` works with the distinct pieces of the input segments ``parts``).
        The per-step work is small, so it runs on ``e.som.threads`` intra-op threads.
        """
        m = self.e.som.method
        with intra_op_threads(self.e.som.threads, cap=True):  # maps of one schedule train in one loop
            return fit_together([(som, dict(patterns=X, order=order, method=m, parts=parts if m == "windowed" else None))
                                 for som, X, order, parts in jobs])

    @torch.no_grad()
    def babble(self, steps: int) -> dict:
        """Motor babbling (a)-(g) of 5.2.1 D, per participant -> patterns ``(P, steps)`` of indices.

        (a) random wrist posture (one of the 7) holding a random object; (b) random direction and
        number of 30-deg rotations that stay in [-90, 90] (0 = keep still); (c) the final posture
        is the desired one (PMC_1); each step records (object, current, desired, action, next).
        """
        gens = participant_generators(self.seed, self.c1.participants, stream=8)
        out = {k: [] for k in ("obj", "cur", "des", "act", "nxt")}
        for gen in gens:
            rec = {k: [] for k in out}
            while len(rec["obj"]) < steps:
                obj = int(torch.randint(2, (1,), generator=gen))
                start = int(torch.randint(7, (1,), generator=gen))
                dr = 1 if int(torch.randint(2, (1,), generator=gen)) else -1  # +1 = counter-clockwise
                room = 6 - start if dr > 0 else start
                nr = int(torch.randint(room + 1, (1,), generator=gen))
                goal = start + dr * nr
                cur = start
                for _ in range(nr + 1):
                    act = 0 if cur == goal else dr  # -1 = N1 (clockwise), 0 = N2, +1 = N3
                    for k, v in zip(rec, (obj, cur, goal, act, cur + act)):
                        rec[k].append(v)
                    cur += act
            for k in out:
                out[k].append(rec[k][:steps])
        return {k: torch.tensor(v) for k, v in out.items()}

    @torch.no_grad()
    def fit(self, images: dict[tuple[int, float], torch.Tensor]) -> dict:
        """Train every connection; the budgets, and where they and the training order depart from
        Table 5.1, are in the module docstring. ``images[(obj, angle)]``: 1024-vector edge maps."""
        e = self.e
        P = self.c1.participants
        ang = torch.tensor(ANGLES)
        items = [(o, a) for o in (0, 1) for a in ANGLES]
        img = torch.stack([images[it] for it in items])  # (14, 1024)
        # C1: every image pre-activates the 7 postures at 0.2; C6: the target image selects its own
        all7 = self.pmc1_code(ang, e.preactivation).sum(0)
        seq = list(range(14)) * e.c1_epochs
        self.train()
        self.c1.learn(img[seq], all7.expand(len(seq), -1), sequence=True)
        own = self.pmc1_code(torch.tensor([a for _, a in items]), e.bias)
        self.c6.learn(img[seq], own[seq], sequence=True)
        # babbling stream: the SOM M1_1 (C7, C8) first, over all som_iterations steps; then C9, C10 and
        # C2 on the first hebb_steps steps of the same stream, C9 and C10 from the trained M1_1's clusters
        # (the thesis trains them step by step alongside the SOM; Table 5.1 gives C2 84 cycles, not 1,960)
        T = max(e.som.iterations, e.hebb_steps)
        b = self.babble(T)
        ai = lambda a: (a + 0).long()  # noqa: E731  (index 0..6)
        pat = b["obj"] * 49 + ai(b["cur"]) * 7 + ai(b["des"])  # (P, T) index into 98 patterns
        objs, curs, dess = torch.meshgrid(torch.arange(2), torch.arange(7), torch.arange(7), indexing="ij")
        objs, curs, dess = objs.reshape(-1), curs.reshape(-1), dess.reshape(-1)
        X = torch.cat([self.ss_code(objs, ang[curs]), self.pmc1_code(ang[dess])], -1)  # (98, 6200)
        # matching SOM PFC_2 on the 196 (PP, PFC_1) pairs: independent of M1_1, so both maps train together
        pairs = [(i, j) for i in range(14) for j in range(14)]
        Y = torch.stack([torch.cat([img[i], img[j]]) for i, j in pairs])
        gens = participant_generators(self.seed, P, stream=9)
        self.fit_soms([(self.m11, X, pat[:, : e.som.iterations], (SS_UNITS, SS_UNITS)),  # [SS, PMC_1]
                       (self.pfc2, Y, seeding.randint(gens, Y.shape[0], (e.som.iterations,)), (PP_UNITS, PP_UNITS))])  # [PP, PFC_1]
        Th = e.hebb_steps
        table = self.m11_table(torch.arange(2).repeat_interleave(7), ang.repeat(2))  # SS codes of the 14 postures
        ids = torch.arange(98)
        m_act = self.som_bump(self.m11, bmu=table((ids // 7).expand(P, -1), (ids % 7).expand(P, -1)))  # (P, 98, 4096)
        acts = self.m12.flat(self.m12.encode(torch.stack([torch.full((3,), 4.5), torch.tensor([4.5, 14.5, 24.5])], -1)))
        nxt_idx = b["obj"][:, :Th] * 7 + b["nxt"][:, :Th]
        ss_set = self.ss_code(torch.tensor([o for o, _ in items]), torch.tensor([a for _, a in items]))  # (14, 3100)
        # C9 and C10 see the same M1_1 sequence (participant p: m_act[p, pat[p, :Th]], Th x 4096)
        # of the finished SOM; C9: M1_1 cluster -> executed command, C10: M1_1 cluster -> next SS posture
        m11_seq = IndexedRows(m_act, pat[:, :Th])
        self.c9.learn(m11_seq, IndexedRows(acts, b["act"][:, :Th] + 1), sequence=True)
        self.c10.learn(m11_seq, IndexedRows(ss_set, nxt_idx), sequence=True)
        # C2: next SS posture -> its image, on the same hebb_steps babbling steps (1,960 presentations of
        # the 14 posture/image pairs; Table 5.1 lists C2 with 14 patterns and 84 cycles, as C1 and C6)
        self.c2.learn(IndexedRows(ss_set, nxt_idx), IndexedRows(img, nxt_idx), sequence=True)
        # C5: PFC_2's cluster to the answer clusters
        same = torch.tensor([items[i][0] == items[j][0] for i, j in pairs])
        order = torch.stack([torch.cat([torch.randperm(196, generator=g_) for _ in range(e.c5_epochs)]) for g_ in gens])
        p_act = self.som_bump(self.pfc2, Y.expand(P, -1, -1))
        ans = self.pmc2.flat(self.pmc2.encode(torch.tensor([[4.5, 4.5], [4.5, 14.5]])))
        self.c5.learn(IndexedRows(p_act, order), IndexedRows(ans, (~same[order]).long()), sequence=True)
        # what each trained weight is formed from, for compact_state (key: the state_dict entry);
        # a SOM trained by another method than 'windowed' leaves none: its weights are saved in full
        self._factors = learnt_factors(self)
        self.eval()
        return {"m11_patterns": X, "pfc2_patterns": Y}

    # ------------------------------------------------------------------ a trial
    @torch.no_grad()
    def trial(self, pp0, pfc1, condition: str = "none", record: int = 0) -> dict:
        """Rotate ``pp0`` ``(P, B, 1024)`` toward the target ``pfc1`` and answer.

        condition: ``none`` (no proprioceptive input to SS), ``match`` (SS feels the actual wrist,
        which starts at the seen object's posture and executes every M1_2 command) or ``mismatch``
        (a random one of the 7 posture clusters every step, from the participant's generator).
        The felt posture pre-activates SS (the field starts at rest + proprioceptive input) and
        stays on during the competition, at ``proprio_gain`` of the forward model's strength.
        Only the two images reach the model. ``rotated_ok`` scores the rotation against the desired
        posture the model itself selected; ``final_angle`` and ``stopped`` let the caller score it
        against the target's true orientation.

        Every large product here has an input drawn from a small finite set (the 14 images, the
        M1_1 winner, the SS winner), so it is computed once per distinct input and looked up
        (:class:`RowCache`); the numbers are those of the product over the whole batch up to float
        rounding (a product of other shapes may sum in another order).
        """
        e = self.e
        P, B, _ = pp0.shape
        gens = participant_generators(self.seed, P, stream=10)
        st = self._trial_start(pp0, pfc1)
        frames = [[] for _ in range(record)]
        for _ in range(e.max_cycles):
            bmu = st.table(st.ss_i, st.des_i)  # (P, B) M1_1 winner
            a9, pred = st.motor(bmu)
            a = a9.reshape(P, B, 10, 3, 10).sum((-3, -1)).argmax(-1)  # 0 N1, 1 N2, 2 N3
            st.stopped |= st.live & (a == 1)
            st.live = st.live & (a != 1)
            if not st.live.any():
                break
            self._rotation_step(st, a, pred, condition, gens)
            if record:
                self._record_step(frames, st, bmu)
        col_angle = self.ss.coords[:SS_COLS, 1]
        final = col_angle[st.ss.reshape(P, B, SS_ROWS, SS_COLS).amax(-2).argmax(-1)]
        ok = st.stopped & ((final - st.desired).abs() < ROTATED_WITHIN_DEG)
        act, d, yes = self._answer(st.pp, pfc1)
        st.rt += d.cycles
        for k in range(record):
            frames[k].append({"PP": st.pp[0, k].reshape(PP_SIDE, PP_SIDE), "PFC_1": pfc1[0, k].reshape(PP_SIDE, PP_SIDE),
                              "PFC_2": act[0, k].reshape(M1_SIDE, M1_SIDE), "PMC_2": d.state[0, k].reshape(10, 20)})
        return {"steps": st.steps, "rotated_ok": ok, "final_angle": final, "stopped": st.stopped, "yes": yes,
                "rt": st.rt, "frames": frames}

    def _trial_start(self, pp0, pfc1) -> SimpleNamespace:
        """The state of a trial before the first rotation step: the desired posture (C1
        pre-activation + C6 bias, strongest column wins), the seen object and its posture (C2 read
        backwards, image -> posture; the actual wrist starts there), the SS code, the counters, and
        the trial's lookups (:meth:`_lookups`)."""
        P, B, _ = pp0.shape
        ang = torch.tensor(ANGLES)
        col_angle = self.ss.coords[:SS_COLS, 1]
        pm = distinct_rows(self.c1.net, pp0) + distinct_rows(self.c6.net, pfc1)
        desired = col_angle[pm.reshape(P, B, SS_ROWS, SS_COLS).amax(-2).argmax(-1)]
        desired = ang[_nearest_posture(desired)]
        s0 = distinct_rows(self.c2.net_reverse, pp0).reshape(P, B, SS_ROWS, SS_COLS)
        col = s0.amax(-2).argmax(-1)
        row = s0.gather(-1, col[..., None, None].expand(P, B, SS_ROWS, 1)).squeeze(-1).argmax(-1)
        obj = (row >= OBJECT_B_ROW).long()
        cur = ang[_nearest_posture(col_angle[col])]
        ss_set, table, motor, image = self._lookups()
        ss_i = obj * 7 + _nearest_posture(cur)
        return SimpleNamespace(
            desired=desired, des_i=_nearest_posture(desired), obj=obj, ss_i=ss_i, ss=ss_set[ss_i], wrist=_nearest_posture(cur),
            pp=pp0.clone(), steps=torch.zeros(P, B, dtype=torch.long), rt=torch.zeros(P, B, dtype=torch.long),
            live=torch.ones(P, B, dtype=torch.bool), stopped=torch.zeros(P, B, dtype=torch.bool),
            ss_set=ss_set, table=table, motor=motor, image=image)

    def _rotation_step(self, st: SimpleNamespace, a, pred, condition: str, gens) -> None:
        """One rotation step of the live trials, in place on ``st``: the SS competition over the
        forward prediction ``pred`` (and the felt posture), the image of its winner (C2)."""
        e = self.e
        P, B = a.shape
        grid = _peak_normalised(pred).reshape(P, B, SS_ROWS, SS_COLS)
        prof = grid.amax(-2)
        u0 = None
        if condition != "none":
            pro = self._felt_posture(st, a, condition, gens)
            prof = prof + pro
            u0 = e.field.h + e.field.gain * pro  # proprioception pre-activates SS
        d = self.ss_field(e.field.gain * prof, max_cycles=e.field.max_cycles, u0=u0)
        col = torch.where(d.decided, d.winner, prof.argmax(-1))
        row = grid.gather(-1, col[..., None, None].expand(P, B, SS_ROWS, 1)).squeeze(-1).argmax(-1)
        new_obj = (row >= OBJECT_B_ROW).long()
        new_i = 14 + new_obj * SS_COLS + col
        (img,) = st.image(new_i)
        img = (_peak_normalised(img) >= e.image_threshold).float()
        live = st.live
        st.rt += torch.where(live, d.cycles, torch.zeros_like(d.cycles))
        st.ss_i = torch.where(live, new_i, st.ss_i)
        st.ss = st.ss_set[st.ss_i]
        st.obj = torch.where(live, new_obj, st.obj)
        st.pp = torch.where(live.unsqueeze(-1), img, st.pp)
        st.steps += live.long()

    def _felt_posture(self, st: SimpleNamespace, a, condition: str, gens) -> torch.Tensor:
        """The proprioceptive input to SS ``(P, B, 100)``: the actual wrist, which executes the M1_2
        command ``a`` (``match``), or a random posture from each participant's generator
        (``mismatch``), as the trained posture code at ``proprio_gain``."""
        ang = torch.tensor(ANGLES)
        if condition == "match":  # the wrist executes the M1_2 command (N1 -1, N2 0, N3 +1 posture)
            st.wrist = torch.where(st.live, (st.wrist + a - 1).clamp(0, 6), st.wrist)
            felt = ang[st.wrist]
        else:
            felt = ang[torch.stack([torch.randint(7, (a.shape[1],), generator=g_) for g_ in gens])]
        felt_i = st.obj * 7 + _nearest_posture(felt)  # one of the 14 trained postures
        return self.e.proprio_gain * st.ss_set[:14].reshape(14, SS_ROWS, SS_COLS).amax(-2)[felt_i]

    def _record_step(self, frames: list, st: SimpleNamespace, bmu) -> None:
        """A frame per recorded trial after a rotation step: PP, SS and the M1_1 cluster."""
        record = len(frames)
        m = self.som_bump(self.m11, bmu=bmu[:1, :record])
        for k in range(record):
            frames[k].append({"PP": st.pp[0, k].reshape(PP_SIDE, PP_SIDE).clone(), "SS": st.ss[0, k].reshape(SS_ROWS, SS_COLS).clone(),
                              "M1_1": m[0, k].reshape(M1_SIDE, M1_SIDE).clone()})

    def _answer(self, pp, pfc1):
        """The answer to the last image ``pp`` and the target ``pfc1``: PFC_2's cluster, C5 and the
        PMC_2 field. Returns PFC_2's activity, the field's decision and ``yes`` ``(P, B)``."""
        act = self.som_bump(self.pfc2, bmu=distinct_rows(lambda x: self.pfc2.bmu(x), torch.cat([pp, pfc1], -1)))
        s = _peak_normalised(self.c5.net(act))
        d = self.answer_field(self.e.field.gain * self.pmc2.unflat(s), max_cycles=self.e.field.max_cycles)
        win = torch.where(d.decided, d.winner, s.argmax(-1))
        return act, d, (win % 20) < 10

    def _lookups(self):
        """What a trial looks up, built once per set of trained weights (and reused by every
        condition): the SS codes (the 14 trained postures, then every (object, column) field
        winner), the M1_1 winner table of :meth:`m11_table` over them, and :class:`RowCache` s of
        C9 / C10 by M1_1 winner and of C2 by SS code."""
        key = tuple(b.weights_version() for b in (self.m11, self.c9, self.c10, self.c2))
        if getattr(self, "_lookup_cache", (None,))[0] != key:
            ang = torch.tensor(ANGLES)
            col_angle = self.ss.coords[:100, 1]
            P = self.c1.participants
            ss_obj = torch.cat([torch.arange(2).repeat_interleave(7), torch.arange(2).repeat_interleave(100)])
            ss_ang = torch.cat([ang.repeat(2), col_angle.repeat(2)])
            ss_set = self.ss_code(ss_obj, ss_ang)  # (214, 3100)
            table = self.m11_table(ss_obj, ss_ang)
            motor = RowCache(P, self.m11.units, self._m11_outputs)  # C9 (action), C10 (forward prediction)
            image = RowCache(P, ss_set.shape[0], lambda i: (self.c2.net(ss_set[i]),))  # C2: image of an SS code
            self._lookup_cache = (key, (ss_set, table, motor, image))
        return self._lookup_cache[1]

    def _m11_outputs(self, bmu: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """C9 and C10 net input of the M1_1 cluster around each winner ``bmu`` ``(P, L)``."""
        m = self.som_bump(self.m11, bmu=bmu)
        return self.c9.net(m), self.c10.net(m)


def _peak_normalised(x: torch.Tensor) -> torch.Tensor:
    """``x`` scaled to a peak of 1 along its last axis (a peak below ``PEAK_FLOOR`` counts as it)."""
    return x / x.amax(-1, keepdim=True).clamp_min(PEAK_FLOOR)


def _nearest_posture(angle: torch.Tensor) -> torch.Tensor:
    """The index in ``ANGLES`` of the posture nearest to each ``angle`` (deg)."""
    return (angle.unsqueeze(-1) - torch.tensor(ANGLES)).abs().argmin(-1)
