"""The change a learning rule computes, which the learner owning the weights applies.

One contract for every rule and every learner: ``rule.delta(weight, pre=..., **activity)``
computes the change at the given weights without touching them and returns a :class:`Change`;
the learner (a connection, a SOM) adds it to its weights in place with :meth:`Change.apply_`,
under ``torch.no_grad()``, after every rule of the step has computed its change at the same
weights. A change knows its dense form (:meth:`Change.tensor`, the weights' shape), so
``weight + rule.delta(weight, ...)`` is the weights after the step; its in-place form touches
only what the rule changes, in the order the rule's own arithmetic gives (the same numbers):

* :class:`Dense`: any change, as a tensor of the weights' shape;
* :class:`Outer`: ``-shrink * W + alpha post^T pre`` (Hebbian decay and outer product; the delta
  rule without decay), applied as one scaling and one fused product;
* :class:`Rows`: new values of a few weight rows (a rule that changes the rows of the units it
  trains and leaves the others);
* :class:`RowSteps`: ``W[p, j] += alpha x`` for a list of rows, in order (one-row updates such as
  Q-learning's).
"""
from __future__ import annotations

import torch


class Change:
    """A weight change computed at ``weight``; :meth:`apply_` adds it there in place."""

    def __init__(self, weight: torch.Tensor) -> None:
        self.weight = weight  # the weights it was computed at

    def tensor(self) -> torch.Tensor:
        """The change as a tensor of the weights' shape."""
        raise NotImplementedError

    def apply_(self, weight: torch.Tensor) -> None:
        """Add the change to ``weight`` (the weights it was computed at) in place."""
        weight.add_(self.tensor())

    # a change reads as the tensor it is: W + change (a tensor: the weights after the step),
    # change * 0.5 and the sum of changes (changes)
    def __add__(self, other):
        if isinstance(other, (int, float)) and other == 0:
            return self
        if isinstance(other, Change):
            return Dense(self.weight, self.tensor() + other.tensor())
        return self.tensor() + other

    __radd__ = __add__

    def __mul__(self, factor):
        return Dense(self.weight, self.tensor() * factor)

    __rmul__ = __mul__

    def __neg__(self):
        return Dense(self.weight, -self.tensor())


class Dense(Change):
    """A change given as a tensor of the weights' shape."""

    def __init__(self, weight: torch.Tensor, change: torch.Tensor) -> None:
        super().__init__(weight)
        self.change = change

    def tensor(self) -> torch.Tensor:
        return self.change


class Outer(Change):
    """``-shrink * W + alpha * post^T pre`` summed over the batch: ``post`` ``(P, B, out)``, ``pre``
    ``(P, B, in)``, ``shrink`` broadcastable to the weights ``(P, out, in)`` or None (no decay)."""

    def __init__(self, weight: torch.Tensor, shrink: torch.Tensor | None, post: torch.Tensor, pre: torch.Tensor,
                 alpha: float) -> None:
        super().__init__(weight)
        self.shrink, self.post, self.pre, self.alpha = shrink, post, pre, alpha

    def tensor(self) -> torch.Tensor:
        if self.shrink is None:
            return torch.bmm(self.post.transpose(1, 2), self.pre).mul_(self.alpha)
        d = self.weight * (-self.shrink)
        return d.baddbmm_(self.post.transpose(1, 2), self.pre, alpha=self.alpha)  # fused

    def apply_(self, weight: torch.Tensor) -> None:
        """Two passes over the weights (a scaling, a fused product), the change never formed."""
        if self.shrink is not None:
            weight.mul_(1.0 - self.shrink)
        weight.baddbmm_(self.post.transpose(1, 2), self.pre, alpha=self.alpha)


class Rows(Change):
    """New values of some weights: ``weight[p, j, cols]`` becomes ``values`` for each
    ``(p, j, cols, values)`` of ``rows`` (``cols`` a boolean mask or index of the row's inputs,
    ``None`` for all)."""

    def __init__(self, weight: torch.Tensor, rows: list) -> None:
        super().__init__(weight)
        self.rows = rows

    def tensor(self) -> torch.Tensor:
        new = self.weight.clone()
        self.apply_(new)
        return new - self.weight

    def apply_(self, weight: torch.Tensor) -> None:
        for p, j, cols, values in self.rows:
            if cols is None:
                weight[p, j] = values
            else:
                weight[p, j, cols] = values


class RowSteps(Change):
    """``weight[p, j] += alpha * x`` for each ``(p, j, x, alpha)`` of ``steps``, in order."""

    def __init__(self, weight: torch.Tensor, steps: list) -> None:
        super().__init__(weight)
        self.steps = steps

    def tensor(self) -> torch.Tensor:
        d = torch.zeros_like(self.weight)
        self.apply_(d)
        return d

    def apply_(self, weight: torch.Tensor) -> None:
        for p, j, x, alpha in self.steps:
            weight[p, j].add_(x, alpha=alpha)


def as_change(weight: torch.Tensor, change) -> Change:
    """``change`` as a :class:`Change` (a tensor is a :class:`Dense` one)."""
    return change if isinstance(change, Change) else Dense(weight, change)
