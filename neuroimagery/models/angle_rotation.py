"""The demo's model (:mod:`neuroimagery.experiments.demo.protocol`): mental rotation of a population-coded angle.

Maps ``ANGLE`` and ``POSTURE`` (1-D population codes, -90..90 deg); connections ``affordance``
(ANGLE -> POSTURE) and ``forward`` (POSTURE -> ANGLE) learn by outstar Hebbian learning (eq.
4.2-4.3); repeating affordance -> forward rotates the imagined angle toward 0, and a two-unit
dynamic field answers "same" / "different" from the overlap of the final code with the upright
target.
"""
from __future__ import annotations

import torch

from ..nn import AllToAll, DynamicField, Hebbian, PopulationMap, monitor, participant_generators


class AngleRotationModel(torch.nn.Module):
    """The demo's model; ``e`` holds the settings of :class:`neuroimagery.experiments.demo.config.DemoConfig`."""

    def __init__(self, e, participants: int, seed: int) -> None:
        super().__init__()
        self.e = e
        self.angle = PopulationMap("ANGLE", (e.units,), -90, 90, e.sigma_deg)
        self.posture = PopulationMap("POSTURE", (e.units,), -90, 90, e.sigma_deg)
        gens = participant_generators(seed, participants, stream=0)
        self.affordance = AllToAll(e.units, e.units, init=(0, 0.1), generators=gens, rules=Hebbian(e.eta), name="affordance")
        gens = participant_generators(seed, participants, stream=1)
        self.forward_model = AllToAll(e.units, e.units, init=(0, 0.1), generators=gens, rules=Hebbian(e.eta), name="forward")
        self.field = DynamicField((2,), tau=5.0, a_exc=0.0, a_inh=0.8, threshold=0.3, name="answer")

    @property
    def participants(self) -> int:
        return self.affordance.participants

    @torch.no_grad()
    def fit(self, seed: int) -> None:
        P = self.affordance.participants
        train_angles = torch.arange(-90.0, 90.1, self.e.step_deg)
        gens = participant_generators(seed, P, stream=2)
        for epoch in range(self.e.epochs):
            order = torch.stack([torch.randperm(len(train_angles), generator=g) for g in gens])  # (P, N)
            for k in range(order.shape[1]):
                a = train_angles[order[:, k]]  # (P,)
                x = self.angle.encode(a).unsqueeze(1)  # (P, 1, n)
                self.affordance.learn(x, self.posture.encode(a).unsqueeze(1))
                nxt = a - torch.sign(a) * torch.minimum(a.abs(), torch.tensor(self.e.step_deg))
                self.forward_model.learn(self.posture.encode(a).unsqueeze(1), self.angle.encode(nxt).unsqueeze(1))
            if monitor.active():  # the training curve: recall error on every training angle after each epoch
                self._record_recall(train_angles, (epoch + 1) * len(train_angles))

    def _record_recall(self, angles: torch.Tensor, step: int) -> None:
        """Mean squared error of the affordance (angle -> posture) and the forward model (posture ->
        next angle) on ``angles``, each output scaled to its peak, as ``train/<connection>/recall_error``."""
        x, post = self.angle.encode(angles), self.posture.encode(angles)
        nxt = self.angle.encode(angles - torch.sign(angles) * torch.minimum(angles.abs(), torch.tensor(self.e.step_deg)))
        for conn, a, b in ((self.affordance, x, post), (self.forward_model, post, nxt)):
            y = conn(a.unsqueeze(0).expand(self.participants, -1, -1))
            y = y / y.amax(-1, keepdim=True).clamp_min(1e-9)
            monitor.record(f"train/{conn.name}/recall_error", (y - b).pow(2).sum(-1).mean(), step)

    @torch.no_grad()
    def trial(self, angles: torch.Tensor, generators, logger=None, tag: str = "") -> dict:
        """Rotate ``angles`` ``(P, B)`` toward 0; returns steps, final angle, answer and RT ``(P, B)``."""
        code = self.angle.encode(angles)
        steps = torch.zeros(angles.shape, dtype=torch.long)
        live = torch.ones(angles.shape, dtype=torch.bool)
        for s in range(self.e.max_steps):
            posture = self.affordance(code)
            at_centre = self.posture.decode(posture, "argmax").abs() < self.e.step_deg / 2
            live = live & ~at_centre
            if not live.any():
                break
            nxt = self.forward_model(posture)
            nxt = (nxt / nxt.amax(-1, keepdim=True).clamp_min(1e-9)) ** self.e.sharpen  # keep the bump narrow
            noise = torch.stack([torch.randn(code.shape[1:], generator=g) for g in generators]) * self.e.noise
            code = torch.where(live.unsqueeze(-1), (nxt + noise).clamp_min(0), code)
            steps += live.long()
            if logger is not None:
                logger.maps({"ANGLE": code[0, :1], "POSTURE": posture[0, :1]}, s, prefix=f"{tag}/")
        final = self.angle.decode(code, "argmax")
        target = self.angle.encode(torch.zeros_like(angles))
        overlap = (code * target).sum(-1) / (code.norm(dim=-1) * target.norm(dim=-1)).clamp_min(1e-9)
        d = self.field(torch.stack([overlap, 1 - overlap], -1), max_cycles=500)
        rt = steps * self.e.cycles_per_step + d.cycles
        return {"steps": steps, "final": final, "answer_same": d.winner == 0, "rt": rt, "rotated_ok": final.abs() < self.e.step_deg}
