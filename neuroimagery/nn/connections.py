"""Connections between maps (thesis section 4.3, eq. 4.4) with in-place local learning.

A connection holds its weights as a buffer - ``(P, out, in)``, one weight matrix per simulated
participant, for :class:`AllToAll`; ``(1, out, in)`` shared by all participants for
:class:`HardWired`; ``(P, 1, n)``, one gain per unit, for :class:`OneToOne` - and computes
``y = F(W x)`` (eq. 4.4; ``F(w * x)`` element-wise for OneToOne) for activity ``x`` of shape
``(P, B, in)``. A 2-D input ``(B, in)`` is treated as one participant and the output is 2-D
again, so a connection drops into an ordinary torch model: its forward is differentiable with
respect to its input, while the weights themselves never require grad.

Learning: ``conn.learn(pre=..., post=..., ...)`` asks each attached rule for its change
(``rule.delta``, a :class:`~.change.Change` computed at the same weights) and applies them in
place under ``torch.no_grad()`` (one rule's structured change touching only what it changes,
several rules' changes summed); it does nothing while the
module is in ``eval()`` mode (warning once per connection) or has no rule. Of the classes here only :class:`AllToAll` takes rules:
:class:`HardWired` has none, and :class:`OneToOne` (a fixed element-wise gain) refuses them with a
``ValueError``. :class:`GainField` has no weights.
"""
from __future__ import annotations

import math
import warnings
from typing import Iterable, Sequence

import torch
from torch import nn

from . import seeding
from .change import Dense, as_change
from .forms import Form, register
from .functional import (as_batched, check_participants, check_tensor, checks_enabled, gain_field,
                         participants_weight, transfer)
from .learning import learn_sequence, run_plain
from .readout import Readouts
from .rules import STEP_BOUND, Rule


class Connection(Readouts, nn.Module):
    """Base class: a weight buffer ``(P, out, in)``, a transfer function, and learning rules.

    ``name`` appears in error messages and training-curve tags; without one a connection is named
    after its class and sizes, e.g. ``AllToAll(37->13)``.

    A connection computes in the dtype of its input (weights of another floating dtype are cast
    for the product, the buffer keeps its own); :meth:`learn` casts the activity to the weights'
    dtype, so the weights keep theirs. Integer and boolean activity is refused, naming the
    connection.
    """

    def __init__(self, n_in: int, n_out: int, weight: torch.Tensor, transfer_fn: str = "identity",
                 rules: Rule | Iterable[Rule] = (), name: str = "", copy: bool = True) -> None:
        super().__init__()
        name = name or f"{type(self).__name__}({n_in}->{n_out})"
        if n_in < 1 or n_out < 1:
            raise ValueError(f"connection {name!r}: n_in and n_out must be >= 1, got {n_in}, {n_out}")
        self.n_in, self.n_out, self.name = int(n_in), int(n_out), name
        self.transfer_name = transfer_fn
        self.F = transfer(transfer_fn)
        # ``copy=False``: a subclass hands over weights it has just made, kept without a copy
        self.register_buffer("weight", weight.detach().clone() if copy else weight.detach())
        self.rules = nn.ModuleList([rules] if isinstance(rules, Rule) else list(rules))
        self.learnt_factors: dict | None = None  # what a closed-form sequence formed the weights from
        self.warned_eval = False  # learn() in eval() mode has warned once
        self.warned_step = False  # a step beyond a rule's stated bound has warned once

    @property
    def participants(self) -> int:
        return self.weight.shape[0]

    def _weight_for(self, xb: torch.Tensor, given: Sequence[int]) -> torch.Tensor:
        """The weights for the batched input ``xb`` (``given``: its shape as passed): expanded if
        shared, in the input's dtype; an error naming the connection if the participants differ."""
        return participants_weight(f"connection {self.name!r}", self.weight, xb, given)

    block_kind = "connection"

    def net(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """Weighted sum ``W x`` before the transfer function, in ``x``'s dtype. The input's shape is
        checked once per configuration, its values at every call unless ``checked`` (the caller
        has checked the batch: the fast path of a model's inner loop)."""
        xb, squeeze = self.batched(x, self.n_in, checked)
        w = self.weight
        if w.shape[0] == 1 and xb.shape[0] != 1:
            w = w.expand(xb.shape[0], *w.shape[1:])
        y = torch.bmm(xb, (w if w.dtype == xb.dtype else w.to(xb.dtype)).transpose(1, 2))
        return y[0] if squeeze and x.dim() == 2 else (y[0, 0] if squeeze else y)

    def forward(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """``F(W x)`` (eq. 4.4)."""
        return self.F(self.net(x, checked=checked))

    @torch.no_grad()
    def learn(self, pre, post=None, return_delta: bool = False, *, sequence: bool = False, batch: int = 1,
              method: str = "auto", progress=None, **kw) -> torch.Tensor | None:
        """Apply every rule's change in place (only in ``train()`` mode).

        One step (default): ``pre`` ``(P, B, in)``, ``post`` ``(P, B, out)``; the ``B`` patterns'
        changes are computed at the same weights. A single rule's structured change (Hebbian, Delta,
        GatedHebbian, QLearning) is applied in place without forming the dense change, and
        ``None`` is returned, unless ``return_delta`` asks for it.

        ``sequence=True``: ``pre``, ``post`` (and ``target``) are sequences of ``T`` steps,
        ``(T, n)`` shared by every participant, ``(P, T, n)``, or
        :class:`~neuroimagery.nn.learning.IndexedRows`, applied in order ``batch`` steps at a time
        (``post=None`` with ``Delta``: the connection's own output at the current weights). The
        implementation is chosen from the rule and the inputs' shape and sparsity among the
        forms registered for the rule and the connection (:mod:`neuroimagery.nn.forms`,
        ``method='auto'``; ``'plain'``: one :meth:`learn` step per group,
        :mod:`neuroimagery.nn.learning`); what a closed form formed the weights from is left in
        ``learnt_factors``. ``progress`` optionally wraps the iterable of steps.
        """
        if not self.learning():
            return None
        if sequence:
            if return_delta:
                raise ValueError("return_delta is for one step, not a sequence")
            learn_sequence(self, pre, post, batch, method, progress, **kw)
            return None
        self._check_needs(post, kw)
        pre_b = self._activity(pre, self.n_in, "pre")
        if post is not None:
            post = self._activity(post, self.n_out, "post")
        for key in ("target",):
            if key in kw and kw[key] is not None:
                kw[key] = self._activity(kw[key], self.n_out, key)
        if not self.warned_step and checks_enabled(pre_b):
            self._check_step(pre_b, post)
        # every rule's change at the same weights (:mod:`.change`), then applied here
        changes = [as_change(self.weight, rule.delta(self.weight, pre=pre_b, post=post, **kw)) for rule in self.rules]
        if len(changes) == 1 and not return_delta and not isinstance(changes[0], Dense):
            # one structured change: added in place, only what it changes touched (the inputs were
            # checked finite while value checks run)
            changes[0].apply_(self.weight)
            return None
        total = sum(c.tensor() for c in changes)
        if checks_enabled(total) and not torch.isfinite(total).all():
            raise FloatingPointError(f"connection {self.name!r}: learning produced non-finite weights")
        self.weight.add_(total)
        return total

    @torch.no_grad()
    def fill_weights_(self, value: float) -> None:
        """Set every weight to ``value`` (e.g. back to a zero start), in place."""
        self.weight.fill_(float(value))

    def _check_needs(self, post, kw) -> None:
        """One error naming the connection and the activity a rule needs and was not given."""
        given = {"post": post, **kw}
        for rule in self.rules:
            missing = [k for k in rule.needs if given.get(k) is None]
            if missing:
                hint = (f" (the actual output: conn.learn(x, conn(x), target=y))" if "post" in missing
                        and "target" in rule.needs else "")
                raise ValueError(f"connection {self.name!r}: {type(rule).__name__}.learn needs "
                                 f"{' and '.join(repr(k) for k in missing)}{hint}")

    def _check_step(self, pre: torch.Tensor, post: torch.Tensor | None) -> None:
        """Warn once when a rule's step gain (:meth:`~.rules.Rule.step_gain`, one reduction over
        this batch's activity) exceeds the bound under which no step can make the error it corrects
        grow (a sufficient condition: above it the weights can diverge, nearly orthogonal patterns
        may still converge), or when the weights are no longer finite."""
        for rule in self.rules:
            gain = rule.step_gain(pre, post)
            if gain is None:
                continue
            g = float(gain)
            if not math.isfinite(g) or g > STEP_BOUND:
                self.warned_step = True
                batch = "" if pre.shape[1] == 1 else f" over a batch of {pre.shape[1]} patterns"
                warnings.warn(
                    f"connection {self.name!r}: a {type(rule).__name__} step{batch} has gain {g:.3g} = "
                    f"{rule.gain_formula()}, above {STEP_BOUND:g}, the bound under which no step can make "
                    "the error it corrects grow; above it the weights can diverge: lower eta, use "
                    "reduction='mean' or smaller batches (this warning is given once)", stacklevel=4)
                return

    def learning(self) -> bool:
        """Whether :meth:`learn` changes the weights now: in ``train()`` mode with a rule. The
        first call in ``eval()`` mode (with a rule) warns that learning is off."""
        if not self.training and len(self.rules) > 0 and not getattr(self, "warned_eval", False):
            self.warned_eval = True
            warnings.warn(f"connection {self.name!r} is in eval() mode: learn() leaves its weights "
                          "unchanged (call .train() to learn; this warning is given once)", stacklevel=4)
        return self.training and len(self.rules) > 0

    def _activity(self, x: torch.Tensor, n: int, what: str) -> torch.Tensor:
        """``x`` ``(P, B, n)`` for a learning step, in the weights' dtype (so they keep it)."""
        name = f"{what} of connection {self.name!r}"
        try:
            xb, _ = as_batched(x, n, name)
        except ValueError as e:
            if "NaN" in str(e) and checks_enabled(self.weight) and not torch.isfinite(self.weight).all():
                raise ValueError(f"{e}: the weights of connection {self.name!r} are no longer finite "
                                 "(learning diverged; a step beyond the rule's bound warns when it happens)") from None
            raise
        check_participants(name, self.participants, xb, x.shape)
        return xb if xb.dtype == self.weight.dtype else xb.to(self.weight.dtype)

    def reset_state(self) -> None:
        """Connections hold no activity; present for a uniform interface."""

    def extra_repr(self) -> str:
        return f"name={self.name!r}, in={self.n_in}, out={self.n_out}, P={self.participants}, F={self.transfer_name}"


class AllToAll(Connection):
    """Every input unit connects to every output unit (Fig. 4.2).

    ``init=(low, high)`` draws initial weights from U[low, high) per participant (thesis: U[0, 0.1]);
    ``init='zeros'`` starts from zero. ``generators`` (one per participant) or ``participants`` +
    ``seed`` set the draws.
    """

    def __init__(self, n_in: int, n_out: int, participants: int = 1, init: str | tuple[float, float] = (0.0, 0.1),
                 generators: Sequence[torch.Generator] | None = None, seed: int = 0, transfer_fn: str = "identity",
                 rules: Rule | Iterable[Rule] = (), name: str = "") -> None:
        if generators is None:
            generators = seeding.participant_generators(seed, participants)
        P = len(generators)
        if init == "zeros":
            w = torch.zeros(P, n_out, n_in)
        elif isinstance(init, (tuple, list)) and len(init) == 2:
            lo, hi = float(init[0]), float(init[1])
            if hi < lo:
                raise ValueError(f"init range must have low <= high, got {init}")
            w = seeding.uniform(generators, (n_out, n_in), lo, hi)
        else:
            raise ValueError(f"init must be 'zeros' or (low, high), got {init!r}")
        super().__init__(n_in, n_out, w, transfer_fn, rules, name, copy=False)


class HardWired(Connection):
    """A fixed weight pattern shared by all participants (no learning), e.g. a flip or a pooling."""

    def __init__(self, matrix: torch.Tensor, transfer_fn: str = "identity", name: str = "") -> None:
        check_tensor("matrix", matrix)
        if matrix.dim() != 2:
            raise ValueError(f"matrix must be 2-D (out, in), got shape {tuple(matrix.shape)}")
        super().__init__(matrix.shape[1], matrix.shape[0], matrix.float().unsqueeze(0), transfer_fn, (), name)

    @classmethod
    def permutation(cls, index: torch.Tensor, name: str = "") -> "HardWired":
        """Output unit ``j`` copies input unit ``index[j]`` (e.g. a mirror or a flip of a map)."""
        n = index.numel()
        m = torch.zeros(n, n)
        m[torch.arange(n), index.long()] = 1.0
        return cls(m, name=name)


class OneToOne(Connection):
    """Unit ``i`` of the input drives unit ``i`` of the output with its own weight ``w_i``.

    Weights are stored as ``(P, 1, n)``, all starting at ``value``; ``y = F(w * x)``. A fixed
    element-wise gain: it has no learning rule (the rules compute ``(P, out, in)`` changes), so
    ``rules`` must be empty and ``learn`` does nothing.
    """

    def __init__(self, n: int, participants: int = 1, value: float = 1.0, transfer_fn: str = "identity",
                 rules: Rule | Iterable[Rule] = (), name: str = "") -> None:
        if isinstance(rules, Rule) or len(list(rules)) > 0:
            raise ValueError("OneToOne is a fixed element-wise gain; it has no learning rule")
        super().__init__(n, n, torch.full((participants, 1, n), float(value)), transfer_fn, (), name)

    def net(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        xb, squeeze = self.batched(x, self.n_in, checked)
        y = xb * self._weight_for(xb, x.shape)
        return y[0] if squeeze and x.dim() == 2 else (y[0, 0] if squeeze else y)


class GainField(nn.Module):
    """Gain-field combination of two 1-D codes into a 2-D map (eq. 6.1, 6.9): ``m_ij = a_i b_j``."""

    def __init__(self, n_a: int, n_b: int, name: str = "") -> None:
        super().__init__()
        self.n_a, self.n_b, self.name = int(n_a), int(n_b), name or f"GainField({n_a}x{n_b})"

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        check_tensor("a", a, (self.n_a,))
        check_tensor("b", b, (self.n_b,))
        return gain_field(a, b)

    def reset_state(self) -> None:
        pass


@register(Rule, Connection)
class Plain(Form):
    """Any rule over a sequence, one :meth:`Connection.learn` step per group (the reference of
    every faster form; :func:`~.learning.run_plain`)."""

    name, priority = "plain", 99

    def run(self, conn, rule, call) -> None:
        run_plain(conn, call.pre, call.post, call.batch, call.progress, **call.kw)
