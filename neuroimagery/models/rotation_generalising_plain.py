"""The Experiment 3 trial (thesis 6.1, Fig. 6.2) written plainly: one participant and one trial at
a time, C6 a dense matrix-vector product over the three PP_1 maps, the equations in the order the
thesis gives them. :meth:`RotationGeneralising.run` computes the same trials batched, C6 as sums of
the weight rows of the active edge pixels; this is its reference (``tests/test_exp3.py`` holds one
against the other). It draws the same random numbers in the same order."""
from __future__ import annotations

import torch

from ..nn.functional import gain_field, softmax_select


def posture_code(model, som, pi: int, x: torch.Tensor) -> torch.Tensor:
    """Participant ``pi``'s graded posture code of image ``x`` (eq. 6.5-6.6): a Gaussian of each
    unit's squared distance to the image, measured from the best unit's."""
    xs = som.rule.scale_input(x)  # the image as the map sees it (sum 1 by default)
    d = som.distances_of(pi, x)
    d = d - d.min()
    if getattr(som.rule, "input_scale", "raw") == "sum":
        d = d / (xs * xs).sum().clamp_min(1e-12)  # in units of the image's squared norm
    return torch.exp(-d / (2 * model.p.posture.code_sigma ** 2))


@torch.no_grad()
def run_plain(model, target: torch.Tensor, rotated: torch.Tensor, generators) -> dict:
    """:meth:`RotationGeneralising.run` of ``model`` for ``target`` / ``rotated`` ``(P, B, n)``, plainly."""
    p, (P, B, n) = model.p, target.shape
    nu = len(p.posture.angles)
    out = {"answer": torch.zeros(P, B, dtype=torch.long), "rotation_steps": torch.zeros(P, B, dtype=torch.long),
           "rotation_deg": torch.zeros(P, B)}
    pp2 = [[rotated[pi, b].clone() for b in range(B)] for pi in range(P)]  # PP_2 starts with the seen image
    done = [[False] * B for _ in range(P)]
    for _ in range(p.selection.max_steps + 1):
        if all(all(d) for d in done):
            break
        for pi, g in enumerate(generators):
            u = torch.rand(B, generator=g)  # one draw per trial and step, decided or not (eq. 6.3)
            for b in range(B):
                if done[pi][b]:
                    continue
                pfc1, x = target[pi, b], pp2[pi][b]
                pmc1 = posture_code(model, model.c3, pi, pfc1)  # PMC_1 (eq. 6.5-6.6)
                ss = posture_code(model, model.c2, pi, x)  # SS
                m11 = gain_field(pmc1, ss).reshape(1, 1, nu * nu)  # M1_1 (eq. 6.1)
                m12 = model.m1_2(m11)  # M1_2 (eq. 6.2)
                move = int(softmax_select(m12[0], p.selection.tau, uniforms=u[b:b + 1])[0])  # eq. 6.3
                if move == 1 or int(out["rotation_steps"][pi, b]) >= p.selection.max_steps:
                    done[pi][b] = True
                    continue
                pp1 = torch.zeros(3 * n)
                pp1[move * n:(move + 1) * n] = x.clamp(0.0, 1.0)  # the image in the PP_1 map of the move (rule R8)
                pp2[pi][b] = model.c6.net_of(pi, pp1)  # C6 (PP_2): the linear output (rule R6)
                out["rotation_deg"][pi, b] += model.step_angles[move]
                out["rotation_steps"][pi, b] += 1
    for pi in range(P):
        for b in range(B):
            pfc2 = model.uncovered(target[pi, b], pp2[pi][b])  # C7 (+1), C8 (-1), rectified
            no = bool(pfc2.sum() > p.match_threshold * target[pi, b].sum()) or int(out["rotation_steps"][pi, b]) >= p.selection.max_steps
            out["answer"][pi, b] = int(no)
    return out
