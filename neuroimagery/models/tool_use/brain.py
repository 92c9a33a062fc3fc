"""One infant robot's maps and connections C1-C4 (thesis Fig. 7.4), in :class:`ToolUseBrain`."""
from __future__ import annotations

import torch
from torch import nn

from ...nn.connections import AllToAll
from ...nn.rules import GatedHebbian, QLearning
from ...nn.som import BidirectionalSOM
from .params import BrainParams
from .common import EVENTS, N_POSTURES


class ToolUseBrain(nn.Module):
    """One infant robot's maps and connections C1-C4 (Fig. 7.4); :meth:`from_params` builds it
    from a :class:`BrainParams`."""

    def __init__(self, image_shape: tuple[int, int], n_dmps: int = 10, n_goals: int = 6,
                 c1_eta: float = 0.1, c2_eta: float = 0.1, c3_eta: float = 0.1, c3_sigma: float = 0.1,
                 c3_action_gain: float = 100.0, q_eta: float = 1e-4, q_gamma: float = 0.8,
                 seed: int = 0) -> None:
        super().__init__()
        self.image_shape = tuple(image_shape)
        self.n_pc = 2 * image_shape[0] * image_shape[1]
        self.n_dmps, self.n_goals = int(n_dmps), int(n_goals)
        self.c3_action_gain = float(c3_action_gain)
        self.c1 = AllToAll(self.n_pc, n_dmps, init="zeros", rules=GatedHebbian(c1_eta), name="C1")
        self.c2 = AllToAll(self.n_pc, n_goals, init="zeros", rules=GatedHebbian(c2_eta), name="C2")
        self.c4 = AllToAll(self.n_pc, n_dmps, init="zeros", rules=QLearning(q_eta, q_gamma), name="C4")
        # C3: a = outcome image (PFC), b = [situation image, gain * primitive code] (PC + PMC)
        self.c3 = BidirectionalSOM(N_POSTURES * n_dmps, self.n_pc, self.n_pc + n_dmps, seed=seed, eta=c3_eta,
                                   sigma=c3_sigma, iterations=1, name="C3")
        self.register_buffer("acquired", torch.zeros(n_dmps, dtype=torch.bool))  # M1 units holding a skill
        self.register_buffer("c3_trained", torch.zeros(N_POSTURES * n_dmps, dtype=torch.bool))
        # the initial situations practised in (Fig. 7.5 B: every posture, success or not)
        self.register_buffer("practised", torch.zeros(N_POSTURES, self.n_pc))
        self.register_buffer("practised_seen", torch.zeros(N_POSTURES, dtype=torch.bool))

    @classmethod
    def from_params(cls, image_shape: tuple[int, int], params: BrainParams, n_dmps: int = 10,
                    seed: int = 0) -> "ToolUseBrain":
        """A brain with ``n_dmps`` PMC / M1 units and the rates and read-outs of ``params``."""
        p = params
        return cls(image_shape, n_dmps=n_dmps, c1_eta=p.c1_eta, c2_eta=p.c2_eta, c3_eta=p.c3_eta, c3_sigma=p.c3_sigma,
                   c3_action_gain=p.c3_action_gain, q_eta=p.eta, q_gamma=p.gamma, seed=seed)

    # --- read-outs
    @staticmethod
    def flat(image: torch.Tensor) -> torch.Tensor:
        return image.reshape(1, -1).float()

    # The read-outs below go through the blocks' fast path (``checked=True``): the PC image is a
    # binary colour-filtered map made by the eye, so its values are not checked again at every
    # read of the 153 600-unit map; the blocks check its shape once.
    def affordance(self, image: torch.Tensor) -> torch.Tensor:
        """C1: mean weight over the active PC units -> (n_dmps,) in [0, 1]."""
        x = self.flat(image)[0]
        return self.c1.net(x, checked=True) / x.sum().clamp_min(1.0)

    def distal_goals(self, image: torch.Tensor) -> torch.Tensor:
        """C2 -> HIP activity (6,) in [0, 1]: which goals this situation is known to afford."""
        x = self.flat(image)[0]
        return self.c2.net(x, checked=True) / x.sum().clamp_min(1.0)

    def q_values(self, image: torch.Tensor) -> torch.Tensor:
        """C4 -> (n_dmps,) action values."""
        return self.c4.net(self.flat(image)[0], checked=True)

    def pmc(self, image: torch.Tensor) -> torch.Tensor:
        """PMC activity: affordance (C1) plus learnt action value (C4), Fig. 7.6."""
        return self.affordance(image) + self.q_values(image)

    def _c3_b(self, image: torch.Tensor, unit: int) -> torch.Tensor:
        code = torch.zeros(1, self.n_dmps)
        code[0, unit] = self.c3_action_gain
        return torch.cat([self.flat(image), code], dim=1)

    def recall_unit(self, image: torch.Tensor, unit: int) -> int:
        """The C3 unit that answers "what if I do primitive ``unit`` in situation ``image``".

        The perceived scene is recognised first, as the nearest of the initial situations the robot
        practised in (all it met in Fig. 7.5 B, whether a movement succeeded there or not); the
        answer is that situation's unit for the intended primitive, trained or not (the mental image
        is constrained by the perceived situation, thesis section 7.1.2).
        """
        if not bool(self.practised_seen.any()):
            return unit
        x = self.flat(image)[0]
        d = (self.practised ** 2).sum(-1) - 2.0 * (self.practised @ x)  # squared distance up to the image's own norm
        d = torch.where(self.practised_seen, d, torch.full_like(d, float("inf")))
        return int(d.argmin()) * self.n_dmps + int(unit)

    def imagine(self, image: torch.Tensor, unit: int) -> torch.Tensor:
        """C3 run backwards: the mental image of doing primitive ``unit`` in situation ``image``.

        The unit found by :meth:`recall_unit` gives its outcome prototype; a unit never trained
        means nothing was learnt for that situation and primitive: no change is imagined.
        """
        winner = self.recall_unit(image, unit)
        if not bool(self.c3_trained[winner]):
            return image.reshape(2, *self.image_shape).float().clone()
        outcome = self.c3.som.prototypes(torch.tensor([winner]), 0, self.n_pc)[0]
        return outcome.reshape(2, *self.image_shape).clamp(0.0, 1.0)

    def maps(self, skills: dict[str, int]) -> dict[str, torch.Tensor]:
        """The learnt weights as images, for TensorBoard: one (H, 2W) map per connection and unit,
        the toy channel of the PC on the left and the tool channel on the right.

        ``C1/<skill>`` (affordance: which PC pixels drive the skill's PMC unit), ``C4/<skill>``
        (its action value), ``C2/<event>`` (distal goals) and ``C3/posture-<p>/<skill>`` (the
        stored outcome image, the mental image of doing the skill in situation p; trained units
        only). ``skills`` maps a skill's name to its PMC unit.
        """
        H, W = self.image_shape

        def side_by_side(row: torch.Tensor) -> torch.Tensor:
            m = row.reshape(2, H, W)
            return torch.cat([m[0], m[1]], dim=1).clone()

        out = {}
        for name, unit in skills.items():
            out[f"C1/{name}"] = side_by_side(self.c1.incoming(unit))
            out[f"C4/{name}"] = side_by_side(self.c4.incoming(unit))
        for k in range(self.n_goals):
            out[f"C2/{EVENTS[k] if k < len(EVENTS) else k}"] = side_by_side(self.c2.incoming(k))
        for name, unit in skills.items():
            for posture in range(1, N_POSTURES + 1):
                label = (posture - 1) * self.n_dmps + unit
                if bool(self.c3_trained[label]):
                    outcome = self.c3.som.prototypes(torch.tensor([label]), 0, self.n_pc)[0]
                    out[f"C3/posture-{posture}/{name}"] = side_by_side(outcome.clamp(0.0, 1.0))
        return out

    def reset_c4(self) -> None:
        """Forget all action values (C4 back to its zero start): a fresh individual's C4."""
        self.c4.fill_weights_(0.0)

    # --- learning (Fig. 7.5 and 7.6)
    def _train_outstar(self, conn: AllToAll, image: torch.Tensor, unit: int, signal: float, times: int) -> None:
        """``times`` outstar steps (eq. 4.2-4.3) toward ``signal`` on output ``unit`` only, through
        the connection's hook (``nn.rules.GatedHebbian``: the other units keep what they learnt)."""
        post = torch.zeros(1, conn.n_out)
        post[0, unit] = float(signal)
        gate = torch.zeros(1, conn.n_out)
        gate[0, unit] = 1.0
        conn.learn(pre=self.flat(image), post=post, gate=gate, repeats=int(times))

    def train_c1(self, image: torch.Tensor, unit: int, signal: float, times: int) -> None:
        """C1 trained for primitive ``unit`` only (the other rows keep what they learnt)."""
        self._train_outstar(self.c1, image, unit, signal, times)

    @torch.no_grad()
    def practise_in(self, posture: int, image: torch.Tensor) -> None:
        """Remember initial situation ``posture`` as seen (for C3's situation recognition)."""
        self.practised[posture - 1] = self.flat(image)[0]
        self.practised_seen[posture - 1] = True

    def train_c2(self, image: torch.Tensor, goal: int, times: int) -> None:
        """C2 trained toward distal goal ``goal`` with teaching signal 1."""
        self._train_outstar(self.c2, image, goal, 1.0, times)

    @torch.no_grad()
    def train_c3(self, image: torch.Tensor, unit: int, posture: int, outcome: torch.Tensor, times: int,
                 generator: torch.Generator) -> None:
        label = (posture - 1) * self.n_dmps + unit
        a, b = self.flat(outcome).unsqueeze(0), self._c3_b(image, unit).unsqueeze(0)
        if not self.training or times < 1:
            return
        # ``times`` presentations of one pair to its forced winner: SOM.fit picks the closed form
        # of those online steps (nn.som_repeated) while the neighbourhood is the winner alone
        self.c3.fit(a, b, labels=torch.tensor([[label]]), iterations=times,
                    order=torch.zeros(1, times, dtype=torch.long))
        self.c3_trained[label] = True

    def q_update(self, x0: torch.Tensor, unit: int, reward: float, x1: torch.Tensor, done: bool) -> None:
        """Eq. 7.1 on C4 for the transition ``x0 --unit--> x1`` through the connection's hook
        (``nn.rules.QLearning``): only the row of ``unit`` changes,
        ``w += eta (r +- gamma qMax(x1) - q_unit(x0)) x0``."""
        self.c4.learn(pre=self.flat(x0), action=torch.tensor([[int(unit)]]), reward=torch.tensor([[float(reward)]]),
                      next_pre=self.flat(x1).unsqueeze(0), done=torch.tensor([[bool(done)]]))

    def reset_state(self) -> None:
        """The brain keeps no activity between trials."""
