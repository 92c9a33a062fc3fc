"""Experiment 3 model: mental rotation with a generalising forward model (thesis section 6.1,
Fig. 6.2).

Maps, batched ``(P, B, n)``: V1 (32x32 edge map); PP_1 (three 32x32 maps: clockwise, none,
counter-clockwise; only the one chosen by M1_2 is active); PP_2 (32x32, predicted image); SS and
PMC_1 (4 units each, wrist postures of the current and of the target image, eq. 6.5-6.6); M1_1
(4x4 gain field, eq. 6.1); M1_2 (3 units n1/n2/n3, eq. 6.2 on the centre of the M1_1 activity,
softmax eq. 6.3); PFC_1 (target),
PFC_2 (PFC_1 - PP_2: +1 one-to-one, -1 from the PP_2 units within ``match_tolerance``) and
PMC_2 (the sum of the rectified PFC_2).

Connections: C6 (PP_1 -> PP_2, all-to-all, delta rule eq. 6.4) is the forward model; C2
(PP_2 -> SS) and C3 (PFC_1 -> PMC_1) are supervised Kohonen maps (eq. 6.7-6.8); the rest are
hard-wired.

Conventions: SS / PMC_1 units are ordered by decreasing angle, so that with M1_1 rows = PMC_1 and
columns = SS the six units above the diagonal (current angle below the target) drive n3, a
counter-clockwise (+45 deg) turn, and the six below drive n1, a clockwise (-45 deg) turn.
"""
from __future__ import annotations

from typing import Sequence

import torch
from torch import nn

from ..nn import AllToAll, Delta, SOM, population_cover
from ..nn.functional import gain_field, softmax_probabilities, softmax_select
from .recording import sample_indices
from .rotation_embodied import fit_posture_soms, posture_maps, triangle_weights

MOVES = ("n1", "n2", "n3")


def posture_code_distances(som: SOM, x: torch.Tensor) -> torch.Tensor:
    """Squared distances of images ``x`` ``(..., n)`` to each unit of ``som``, minus the best unit's,
    divided by the squared norm of the image as the map sees it when the map scales its inputs
    (``input_scale='sum'``: a binary image of K units has squared norm 1 / K, so the division
    multiplies by K and undoes the scaling's shrinking of every distance); as they are otherwise."""
    d = som.distances(x)
    d = d - d.min(-1, keepdim=True).values
    if getattr(som.rule, "input_scale", "raw") == "sum":
        xs = som.rule.scale_input(x)
        d = d / (xs * xs).sum(-1, keepdim=True).clamp_min(1e-12)
    return d


class RotationGeneralising(nn.Module):
    """The Experiment 3 network for ``P`` participants (``generators``: one per participant)."""

    def __init__(self, p, generators: Sequence[torch.Generator], participant_ids: Sequence[int] | None = None) -> None:
        super().__init__()
        self.p = p
        self.participant_ids = list(range(len(generators)) if participant_ids is None else participant_ids)
        n = p.map_size * p.map_size
        self.n, self.size = n, p.map_size
        self.step_angles = (-float(p.step_deg), 0.0, float(p.step_deg))  # n1 cw, n2 none, n3 ccw
        self.c6 = AllToAll(3 * n, n, init=(0.0, p.init_high), generators=generators, rules=Delta(p.fm.eta), name="C6")
        nu = len(p.posture.angles)
        self.c2, self.c3 = posture_maps(p.init_high, p.posture, n, nu, generators, ("C2", "C3"))
        # M1_1 -> M1_2 hard-wired masks: lower-left -> n1, diagonal -> n2, upper-right -> n3
        self.register_buffer("m1_masks", triangle_weights(nu))

    @property
    def participants(self) -> int:
        return self.c2.participants

    def fit_forward_model(self, X: torch.Tensor, Y: torch.Tensor, batch: int, progress=None) -> None:
        """C6 by the delta rule (eq. 6.4) in mini-batches of ``batch`` on the pairs ``X`` ``(P, N, 3n)``
        (the image in the PP_1 block of its movement) -> ``Y`` ``(P, N, n)``."""
        self.train()
        self.c6.learn(X, None, sequence=True, batch=batch, target=Y, progress=progress)

    def fit_posture_maps(self, maps: torch.Tensor, labels: torch.Tensor, generators, progress=None) -> None:
        """C2 and C3 (supervised Kohonen, eq. 6.7-6.8) on edge ``maps`` ``(N, n)`` labelled with
        their posture units; ``progress`` optionally wraps the list of maps."""
        self.train()
        fit_posture_soms([self.c2, self.c3], maps, labels, generators, progress)

    def posture(self, som: SOM, x: torch.Tensor) -> torch.Tensor:
        """Graded posture code (eq. 6.5-6.6): a Gaussian of each unit's distance to the image,
        measured from the best unit's distance, ``exp(-(d_i^2 - d_min^2) / (2 sigma^2))``.

        The distances are those of the image as the map sees it (scaled to sum 1) and are measured
        in units of that image's squared norm, so that ``code_sigma`` means differences of about
        twice the difference of the units' overlap with the image (see :func:`posture_code_distances`)."""
        d = posture_code_distances(som, x)
        return torch.exp(-d / (2 * self.p.posture.code_sigma ** 2))

    def m1_2(self, m11: torch.Tensor) -> torch.Tensor:
        """M1_2 activity (eq. 6.2): a Gaussian of the distance between M1_1 ``(P, B, 16)`` and the
        weights of each of n1, n2, n3.

        M1_1 is a population code (the 2-D Gaussian of eq. 6.1) and is compared with each unit's
        weights by where its activity is centred across the diagonal: the activity-weighted mean of
        (column - row), i.e. of (SS unit - PMC_1 unit), against the same mean of each unit's mask (0
        for the diagonal of n2, -5/3 and +5/3 for the triangles of n1 and n3). Codes that agree, and
        codes that are both flat, put the centre on the diagonal and select n2 (thesis 6.1.3).

        The width is ``sqrt(m1_centre_sigma^2 + var)`` (rule R7), ``var`` the activity-weighted
        variance of (column - row) of M1_1: the response of a unit of Gaussian tuning to an input
        spread with that variance, so that less certain SS / PMC_1 codes give a less certain M1_2
        (thesis 6.1.3). The Gaussian is centred on the nearest unit (its activity is 1), as in the
        posture code of eq. 6.5-6.6.
        """
        d2 = (self.m1_centre(m11).unsqueeze(-1) - self.m1_centre(self.m1_masks)) ** 2  # (P, B, 3)
        sigma = (self.p.m1_centre_sigma ** 2 + self.m1_spread(m11)).sqrt().unsqueeze(-1)  # rule R7
        return torch.exp(-(d2 - d2.min(-1, keepdim=True).values) / (2 * sigma ** 2))

    def m1(self, pmc1: torch.Tensor, pp2: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """SS (C2 on PP_2, eq. 6.5), M1_1 (eq. 6.1) and M1_2 (eq. 6.2) for PMC_1 ``(P, B, nu)``."""
        P, B, nu = pmc1.shape
        ss = self.posture(self.c2, pp2)
        m11 = gain_field(pmc1, ss).reshape(P, B, nu * nu)
        return ss, m11, self.m1_2(m11)

    def move_probabilities(self, target: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
        """P(n1, n2, n3) ``(P, B, 3)`` of a step with PFC_1 = ``target`` and PP_2 = ``image`` (eq. 6.6,
        6.5, 6.1-6.3), the model's own read-out."""
        return softmax_probabilities(self.m1(self.posture(self.c3, target), image)[2], self.p.selection.tau)

    def m1_centre(self, m11: torch.Tensor) -> torch.Tensor:
        """Activity-weighted mean of (column - row) of M1_1 patterns ``(..., nu*nu)``: how far, in
        posture units, the posture of the current image (SS, columns) lies past the desired one
        (PMC_1, rows); 0 for activity on the diagonal or spread evenly over the map."""
        nu = int(round(m11.shape[-1] ** 0.5))
        k = torch.arange(nu, dtype=m11.dtype)
        offset = (k.view(1, -1) - k.view(-1, 1)).reshape(-1)  # column - row of each unit
        return (m11 * offset).sum(-1) / m11.sum(-1).clamp_min(1e-12)

    def m1_spread(self, m11: torch.Tensor) -> torch.Tensor:
        """Activity-weighted variance of (column - row) of M1_1 patterns ``(..., nu*nu)``, in squared
        posture units: how spread the activity is across the diagonal (0 for a single cell)."""
        nu = int(round(m11.shape[-1] ** 0.5))
        k = torch.arange(nu, dtype=m11.dtype)
        offset = (k.view(1, -1) - k.view(-1, 1)).reshape(-1)
        w = m11 / m11.sum(-1, keepdim=True).clamp_min(1e-12)
        mean = (w * offset).sum(-1, keepdim=True)
        return (w * (offset - mean) ** 2).sum(-1)

    def uncovered(self, pfc1: torch.Tensor, pp2: torch.Tensor) -> torch.Tensor:
        """PFC_2: target units not covered by the imagined image (C7 +1, C8 -1, rectified).

        C8 reaches each PFC_2 unit from the PP_2 units within ``match_tolerance`` map units
        (a max over that square neighbourhood), so an edge displaced by resampling a rotated
        image on the 32x32 grid still covers the target edge next to it.
        """
        return (pfc1 - population_cover(pp2, self.size, self.p.match_tolerance)).clamp_min(0.0)

    def forward_step(self, x: torch.Tensor, move: torch.Tensor, active: torch.Tensor | None = None) -> torch.Tensor:
        """PP_1 -> PP_2 through C6: the image sits in the PP_1 map of ``move``, cut to [0, 1] on the
        way from PP_2 (rule R8); PP_2 = the linear output (rule R6)."""
        P, B, n = x.shape
        x_in = x  # a row that does not step keeps PP_2 as it is
        x = x.clamp(0.0, 1.0)  # a binary edge map (the first step) passes unchanged
        sel = torch.ones(P, B, dtype=torch.bool) if active is None else active
        full = torch.zeros(P, B, 3 * n)
        for m in range(3):
            s = ((move == m) & sel).unsqueeze(-1)
            full[..., m * n:(m + 1) * n] = x * s
        return torch.where(sel.unsqueeze(-1), self.c6.net_sparse(full), x_in)

    @torch.no_grad()
    def run(self, target: torch.Tensor, rotated: torch.Tensor, generators, record=0, **_) -> dict:
        """Run a batch of trials (binary edge maps ``(P, B, n)``; PP_2 graded after a step, rule R6); see the module docstring.
        ``record``: the trials of participant 0 whose maps are returned per step (a number of
        leading trials or a sequence of trial indices)."""
        p = self.p
        P, B, _ = target.shape
        nu = len(p.posture.angles)
        pfc1 = target
        pmc1 = self.posture(self.c3, pfc1)
        pp2 = rotated  # at the start PP_2 holds the seen image
        done = torch.zeros(P, B, dtype=torch.bool)
        rotations = torch.zeros(P, B, dtype=torch.long)
        angle = torch.zeros(P, B)
        step_deg = torch.tensor(self.step_angles)
        shown = sample_indices(record, B)
        history: list[list[dict]] = [[] for _ in shown]
        for s in range(p.selection.max_steps + 1):
            act = ~done
            if not bool(act.any()):
                break
            ss, m11, m12 = self.m1(pmc1, pp2)  # eq. 6.5, 6.1, 6.2
            move = softmax_select(m12, p.selection.tau, generators)  # eq. 6.3
            stop = act & ((move == 1) | (rotations >= p.selection.max_steps))
            go = act & ~stop
            new = self.forward_step(pp2, move, go)
            for j, k in enumerate(shown):
                if bool(act[0, k]):
                    maps = {"PFC_1": pfc1[0, k].view(self.size, self.size), "PP_2": pp2[0, k].view(self.size, self.size),
                            "SS": ss[0, k], "PMC_1": pmc1[0, k], "M1_1": m11[0, k].view(nu, nu), "M1_2": m12[0, k],
                            "PFC_2": self.uncovered(pfc1[0, k], pp2[0, k]).view(self.size, self.size)}
                    history[j].append({n: m.clone() for n, m in maps.items()})  # a view would pin the batch
            angle = angle + torch.where(go, step_deg[move], torch.zeros(()))
            rotations = rotations + go.long()
            pp2 = new
            done = done | stop
        pfc2 = self.uncovered(pfc1, pp2)  # C7 (+1), C8 (-1), rectified
        pmc2 = pfc2.sum(-1)  # C9
        no = (pmc2 > p.match_threshold * pfc1.sum(-1)) | (rotations >= p.selection.max_steps)
        return {"answer": no.long(), "rt": rotations.float(), "rotation_steps": rotations, "rotations": rotations,
                "rotation_deg": angle, "decided": rotations < p.selection.max_steps, "history": history}
