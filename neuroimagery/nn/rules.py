"""Local, autograd-free learning rules.

A rule only *computes* a weight change from the activity it is given, ``delta(weight, pre=...,
**activity) -> Change`` (:mod:`.change`); the learner that owns the weights (a connection, a SOM)
applies it in place (:meth:`neuroimagery.nn.connections.Connection.learn`, :meth:`.som.SOM.step`).
Several rules on one connection therefore do not depend on their order.

The delta rule, with its registered forms, is in :mod:`.delta`.

Weights have shape ``(P, out, in)`` (participants first); activities ``(P, B, n)``. Changes from
the ``B`` patterns of a batch are computed at the same weights and added (``reduction='sum'``) or
averaged (``'mean'``); with ``B = 1`` both equal the online rule of the thesis.
"""
from __future__ import annotations

import torch
from torch import nn

from .change import Change, Dense, Outer, RowSteps, Rows
from .functional import check_rate


def _reduce(x: torch.Tensor, reduction: str, batch: int) -> torch.Tensor:
    return x / batch if reduction == "mean" else x


def _on_host(weight: torch.Tensor) -> bool:
    """Whether a rule may read values on the host (CPU weights, not traced by ``torch.compile``):
    the exact scalar forms of :class:`GatedHebbian` and :class:`QLearning` run there; elsewhere the
    same change is formed with tensor operations only (equal up to float rounding)."""
    return weight.device.type == "cpu" and not torch.compiler.is_compiling()


def check_reduction(reduction: str) -> str:
    if reduction not in ("sum", "mean"):
        raise ValueError(f"reduction must be 'sum' or 'mean', got {reduction!r}")
    return reduction


STEP_BOUND = 2.0  # the largest step gain (see Rule.step_gain) at which a step still shrinks what it corrects


class Rule(nn.Module):
    """Base class: ``delta(weight, **activity) -> change`` (a :class:`~.change.Change`, or a tensor
    of the weight's shape), computed at ``weight`` without changing it; the learner applies it.

    ``needs`` names the activity a step cannot do without (a connection refuses a step that lacks
    one, naming it). :meth:`step_gain` is the factor a step multiplies what it corrects by, minus
    one, in the worst direction: above :data:`STEP_BOUND` (2) a step makes that grow instead of
    shrink, so repeated steps diverge; a connection warns once when a step exceeds it."""

    needs: tuple[str, ...] = ()

    def delta(self, weight: torch.Tensor, **kw) -> Change:  # pragma: no cover - interface
        raise NotImplementedError

    def step_gain(self, pre: torch.Tensor, post: torch.Tensor | None) -> torch.Tensor | None:
        """The step's gain (a 0-d tensor) for this batch, or None when the rule states no bound."""
        return None

    def gain_formula(self) -> str:
        """How :meth:`step_gain` is computed, for the warning that quotes it."""
        return ""


class Hebbian(Rule):
    """Hebbian learning in Oja's bounded form (eq. 4.2-4.3).

    ``dw_ij = eta * a_i * (a_j - w_ij)`` for the synapse from neuron ``i`` to neuron ``j``.

    * ``form='outstar'``: ``i`` is the presynaptic unit. The weights leaving an active input unit
      move toward the output pattern, so ``W x`` of a learnt input reproduces its associated output.
      This is how the thesis's associative maps (affordances, forward models) learn.
    * ``form='instar'``: ``i`` is the postsynaptic unit. The weights entering an active output unit
      move toward the input pattern (the rule behind competitive / SOM-like learning).

    Weight ``W[p, j, i]`` connects input ``i`` to output ``j``.
    """

    def __init__(self, eta: float, form: str = "outstar", reduction: str = "sum") -> None:
        super().__init__()
        self.eta = check_rate("eta", eta)
        if form not in ("outstar", "instar"):
            raise ValueError(f"form must be 'outstar' or 'instar', got {form!r}")
        self.form = form
        self.reduction = check_reduction(reduction)

    needs = ("post",)

    def step_gain(self, pre, post):
        """``rate * max_i sum_b a_i``: the decay of eq. 4.3 multiplies each weight by
        ``1 - rate sum_b a_i`` (``a`` the input for the outstar form, the output for the instar);
        beyond 2 that factor is below -1 and the weights oscillate with growing size."""
        scale = self.eta / pre.shape[1] if self.reduction == "mean" else self.eta
        a = pre if self.form == "outstar" else post
        return scale * a.sum(1).amax()

    def gain_formula(self) -> str:
        return f"eta * max_i sum_b a_i (eta={self.eta}, reduction={self.reduction!r}, a the {'input' if self.form == 'outstar' else 'output'})"

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, **_) -> Outer:
        """``-eta w_ji sum_b a_i + eta sum_b y_j x_i``: a decay and an outer product (applied in two
        passes over the weights, the change never formed)."""
        scale = self.eta / pre.shape[1] if self.reduction == "mean" else self.eta
        if self.form == "outstar":
            shrink = scale * pre.sum(1).unsqueeze(1)  # eta sum_b x_i
        else:
            shrink = scale * post.sum(1).unsqueeze(2)  # eta sum_b y_j
        return Outer(weight, shrink, post, pre, scale)

    def extra_repr(self) -> str:
        return f"eta={self.eta}, form={self.form!r}"


class GatedHebbian(Hebbian):
    """Outstar Hebbian change (eq. 4.2-4.3) restricted to the output units being trained, repeated.

    ``gate`` ``(P, out)`` (0/1) says which output units learn: the thesis trains one affordance
    (one goal) at a time and the other units keep what they learnt. ``repeats`` = ``k`` is the
    change of ``k`` identical online steps ``w <- w + eta x (y - w)``. With binary input (a
    colour-filtered map) they have a closed form, ``w <- y + (1 - eta)^k (w - y)`` where ``x = 1``
    (weights of inactive inputs do not move); :meth:`delta` gives the new values of the gated rows
    by it (a :class:`~.change.Rows` change), other inputs take the ``k`` steps one by one. One pattern per participant (``B = 1``). Weights ``(P, out, in)``.
    """

    def __init__(self, eta: float) -> None:
        super().__init__(eta, form="outstar")

    @staticmethod
    def _check(pre: torch.Tensor, gate: torch.Tensor | None, repeats: int) -> None:
        if pre.shape[1] != 1:
            raise ValueError(f"GatedHebbian: one pattern per participant, got {pre.shape[1]}")
        if int(repeats) < 0:
            raise ValueError(f"GatedHebbian: repeats must be >= 0, got {repeats}")
        if gate is not None and not bool(((gate == 0) | (gate == 1)).all()):
            raise ValueError("GatedHebbian: gate must be 0/1")

    def delta(self, weight, pre, post, gate=None, repeats: int = 1, **_) -> Change:
        """The change ``repeats`` steps make: the new values of the gated rows (on the CPU; the
        weights of inactive binary inputs do not move), else the dense change of ``k`` steps."""
        if int(repeats) < 1:
            return Rows(weight, [])
        if not _on_host(weight):  # on a device, on meta or while compiling: k plain steps, no value reads
            g = (torch.ones_like(post) if gate is None else gate.unsqueeze(1).to(post.dtype)).transpose(1, 2)
            new = weight.clone()
            for _ in range(int(repeats)):
                new.add_(self.eta * g * pre * (post.transpose(1, 2) - new))
            return Dense(weight, new - weight)
        self._check(pre, gate, repeats)
        rows = []
        for p in range(weight.shape[0]):
            x, y = pre[p, 0], post[p, 0]
            units = range(weight.shape[1]) if gate is None else torch.nonzero(gate[p]).flatten().tolist()
            binary = bool(((x == 0) | (x == 1)).all())
            on = x > 0
            for j in units:
                target = y[j]
                if binary:  # k steps in closed form on the active inputs
                    rows.append((p, j, on, target + (1.0 - self.eta) ** int(repeats) * (weight[p, j, on] - target)))
                else:
                    row = weight[p, j].clone()
                    for _ in range(int(repeats)):
                        row.add_(self.eta * x * (target - row))
                    rows.append((p, j, None, row))
        return Rows(weight, rows)

    def extra_repr(self) -> str:
        return f"eta={self.eta}, gated outstar"


class Kohonen(Rule):
    """Kohonen self-organising step (eq. 4.5) with decaying rate and radius.

    ``w_k <- w_k + theta_k(t) eta(t) (v - w_k)`` where ``theta_k = exp(-d(k, bmu)^2 / (2 sigma(t)^2))``
    is a Gaussian of the grid distance to the best-matching unit. ``eta`` and ``sigma`` decay
    exponentially from their initial to their final values over ``iterations`` steps.

    Weights ``(P, units, in)``: row ``k`` is unit ``k``'s prototype.
    """

    def __init__(self, eta: float = 0.1, sigma: float = 5.0, iterations: int = 10_000,
                 eta_final: float = 0.01, sigma_final: float = 0.5, cutoff: float = 1e-6) -> None:
        super().__init__()
        self.eta0 = check_rate("eta", eta, open_low=True)
        self.sigma0 = check_rate("sigma", sigma, open_low=True)
        self.eta1 = check_rate("eta_final", eta_final, open_low=True)
        self.sigma1 = check_rate("sigma_final", sigma_final, open_low=True)
        if int(iterations) < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        self.iterations = int(iterations)
        self.cutoff = check_rate("cutoff", cutoff)

    def schedule(self, t: int | torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(eta(t), sigma(t))``, exponential interpolation, constant after ``iterations``."""
        frac = torch.clamp(torch.as_tensor(t, dtype=torch.float32) / max(self.iterations - 1, 1), 0.0, 1.0)
        eta = self.eta0 * (self.eta1 / self.eta0) ** frac
        sigma = self.sigma0 * (self.sigma1 / self.sigma0) ** frac
        return eta, sigma

    def neighbourhood(self, grid: torch.Tensor, bmu: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
        """``theta`` of every unit: ``grid`` ``(units, D)`` coords, ``bmu`` ``(...)`` -> ``(..., units)``."""
        d2 = ((grid[bmu].unsqueeze(-2) - grid) ** 2).sum(-1)
        theta = torch.exp(-d2 / (2.0 * sigma**2))
        return torch.where(theta < self.cutoff, torch.zeros_like(theta), theta)

    needs = ("bmu", "grid")

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, bmu: torch.Tensor, grid: torch.Tensor,
              t: int | torch.Tensor = 0, **_) -> Dense:
        """``pre`` ``(P, 1, in)`` (one pattern per participant), ``bmu`` ``(P,)`` the winners and
        ``grid`` ``(units, D)`` their coordinates (a SOM passes its own); ``t`` the step (a 0-dim
        tensor on the weights' device keeps the step on the device)."""
        eta, sigma = self.schedule(t)
        h = eta * self.neighbourhood(grid, bmu, sigma)  # (P, units)
        return Dense(weight, h.unsqueeze(-1) * (pre[:, 0].unsqueeze(1) - weight))

    def extra_repr(self) -> str:
        return f"eta={self.eta0}->{self.eta1}, sigma={self.sigma0}->{self.sigma1}, iterations={self.iterations}"

    def scale_input(self, x: torch.Tensor) -> torch.Tensor:
        """The input as the rule and the read-out see it (unchanged for the plain Kohonen rule)."""
        return x


INPUT_SCALES = ("auto", "sum", "raw")


class SupervisedKohonen(Kohonen):
    """Supervised Kohonen step (eq. 6.7-6.8, 6.14-6.16).

    The winner is not searched for: it is forced to the unit that codes the known label (e.g.
    the wrist posture the image was seen at). After the Kohonen step each unit's weights are
    normalised to sum to one. The returned change is ``normalised(w + dw) - w``.

    ``input_scale``: with ``'sum'`` each input pattern is divided by its sum before the step (and
    by the maps that read the weights, :meth:`scale_input`), so that it lies on the scale of the
    weights that eq. 6.8 / 6.16 keep summing to one and ``eta`` is the real rate: a raw binary
    image of K active units against a prototype summing to one would otherwise replace about
    ``eta K / (1 + eta K)`` of the prototype per step. ``'raw'`` feeds the pattern as given (the
    literal reading). ``'auto'`` (default) is ``'sum'`` when the weights are normalised, else ``'raw'``.
    """

    def __init__(self, eta: float = 0.1, sigma: float = 1.0, iterations: int = 1000,
                 eta_final: float | None = None, sigma_final: float | None = None, normalise: bool = True,
                 cutoff: float = 1e-6, input_scale: str = "auto") -> None:
        super().__init__(eta, sigma, iterations, eta if eta_final is None else eta_final,
                         sigma if sigma_final is None else sigma_final, cutoff)
        self.normalise = bool(normalise)
        if input_scale not in INPUT_SCALES:
            raise ValueError(f"input_scale must be one of {INPUT_SCALES}, got {input_scale!r}")
        self.input_scale = ("sum" if self.normalise else "raw") if input_scale == "auto" else input_scale

    def scale_input(self, x: torch.Tensor) -> torch.Tensor:
        """``x / sum(x)`` per pattern with ``input_scale='sum'`` (an empty pattern stays empty), else ``x``."""
        if self.input_scale != "sum":
            return x
        return x / x.sum(-1, keepdim=True).clamp_min(1e-12)

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, bmu: torch.Tensor, grid: torch.Tensor,
              t: int | torch.Tensor = 0, **_) -> Dense:
        new = weight + super().delta(weight, pre, bmu, grid, t).tensor()
        if self.normalise:
            new = new / new.sum(-1, keepdim=True).clamp_min(1e-12)
        return Dense(weight, new - weight)


class QLearning(Rule):
    """Q-learning on a connection from a state map to action units (eq. 7.1).

    The action values are ``q = W x``. After the action ``win`` chosen for input ``x_{t-1}``
    earns ``reward_t``, only the weights into ``win`` change:

    * ``form='standard'`` (default): ``dw_{win,i} = eta (reward_t + gamma qMax_t - qWin_{t-1}) x_{i,t-1}``,
      the usual temporal-difference target (no bootstrap term when ``done``).
    * ``form='printed'``: the sign exactly as printed in eq. 7.1,
      ``dw_{win,i} = eta ((reward_t - gamma qMax_t) - qWin_{t-1}) x_{i,t-1}``; see docs/choices.md.

    With one-hot inputs this is tabular Q-learning. Thesis values: eta = 0.0001, gamma = 0.8.
    Weights ``(P, actions, inputs)``; ``pre`` ``(P, B, inputs)`` is ``x_{t-1}``, ``action`` long
    ``(P, B)``, ``reward`` ``(P, B)``, ``next_pre`` ``(P, B, inputs)`` is ``x_t`` (gives ``qMax_t``),
    ``done`` bool ``(P, B)``.
    """

    def __init__(self, eta: float = 1e-4, gamma: float = 0.8, form: str = "standard", reduction: str = "sum") -> None:
        super().__init__()
        self.eta = check_rate("eta", eta)
        self.gamma = check_rate("gamma", gamma, high=1.0)
        if form not in ("standard", "printed"):
            raise ValueError(f"form must be 'standard' or 'printed', got {form!r}")
        self.form = form
        self.reduction = check_reduction(reduction)

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, action: torch.Tensor, reward: torch.Tensor,
              next_pre: torch.Tensor, done: torch.Tensor | None = None, **_) -> Change:
        """Only the chosen action's weights change: on the CPU one row step per pattern, the
        temporal-difference error of each (at the same weights) formed in float64; elsewhere the
        dense change, formed with tensor operations only."""
        if not _on_host(weight):  # on a device, on meta or while compiling
            return Dense(weight, self._dense(weight, pre, action, reward, next_pre, done))
        P, B = pre.shape[:2]
        sign = 1.0 if self.form == "standard" else -1.0
        scale = self.eta / B if self.reduction == "mean" else self.eta
        steps = []
        for p in range(P):
            for b in range(B):
                a = int(action[p, b])
                q_win = float(weight[p, a] @ pre[p, b])
                ended = done is not None and bool(torch.as_tensor(done)[p, b])
                q_max = 0.0 if ended else float((weight[p] @ next_pre[p, b]).max())
                r = float(torch.as_tensor(reward, dtype=torch.float64).broadcast_to((P, B))[p, b])
                steps.append((p, a, pre[p, b], scale * (r + sign * self.gamma * q_max - q_win)))
        return RowSteps(weight, steps)

    def _dense(self, weight, pre, action, reward, next_pre, done) -> torch.Tensor:
        q_prev = torch.einsum("pai,pbi->pba", weight, pre)
        q_win = q_prev.gather(-1, action.unsqueeze(-1)).squeeze(-1)  # (P, B)
        q_max = torch.einsum("pai,pbi->pba", weight, next_pre).max(-1).values
        if done is not None:
            q_max = torch.where(done, torch.zeros_like(q_max), q_max)
        reward = torch.as_tensor(reward, dtype=weight.dtype, device=weight.device)
        sign = 1.0 if self.form == "standard" else -1.0
        err = reward + sign * self.gamma * q_max - q_win  # (P, B)
        onehot = torch.nn.functional.one_hot(action, weight.shape[1]).to(weight.dtype)  # (P, B, A)
        d = torch.einsum("pba,pb,pbi->pai", onehot, err, pre)
        return self.eta * _reduce(d, self.reduction, pre.shape[1])

    def extra_repr(self) -> str:
        return f"eta={self.eta}, gamma={self.gamma}, form={self.form!r}"


__all__ = ["Rule", "Hebbian", "GatedHebbian", "Kohonen", "SupervisedKohonen", "QLearning"]


class Sanger(Rule):
    """Sanger's generalised Hebbian rule (Sanger, 1989): ``dW = eta (y x^T - LT[y y^T] W)`` with
    ``y = W x`` and ``LT`` the lower triangle (diagonal included). The rows of ``W`` converge to the
    principal directions of the inputs, in order of variance. ``sample_weight`` ``(P, B)`` weighs
    each pattern of the batch (all 1 when None); the rate is divided by the weighted mean squared
    norm of the batch's patterns (``normalise=True``), so the step does not depend on the inputs'
    scale."""

    def __init__(self, eta: float = 0.5, normalise: bool = True) -> None:
        super().__init__()
        self.eta = check_rate("eta", eta)
        self.normalise = bool(normalise)

    def delta(self, weight: torch.Tensor, pre: torch.Tensor, post: torch.Tensor | None = None,
              sample_weight: torch.Tensor | None = None, **_) -> torch.Tensor:
        P, B, n = pre.shape
        w = pre.new_ones(P, B) if sample_weight is None else sample_weight
        total = w.sum(-1).clamp_min(1e-12).view(P, 1, 1)
        y = torch.bmm(pre, weight.transpose(1, 2)) if post is None else post  # (P, B, m)
        yx = torch.einsum("pb,pbm,pbn->pmn", w, y, pre) / total
        yy = torch.einsum("pb,pbm,pbk->pmk", w, y, y) / total
        d = yx - torch.bmm(torch.tril(yy), weight)
        scale = self.eta
        if self.normalise:
            sq = (torch.einsum("pb,pbn->p", w, pre * pre) / total.view(P)).clamp_min(1e-12)
            return Dense(weight, d * (scale / sq).view(P, 1, 1))
        return Dense(weight, d * scale)

    def extra_repr(self) -> str:
        return f"eta={self.eta}, normalise={self.normalise}"
