"""Registered implementations of the online Kohonen rule (eq. 4.5; supervised eq. 6.7-6.8) that
:meth:`neuroimagery.nn.SOM.fit` chooses from.

One rule, several implementations, as a simulator's builder keeps several kernels for one
learning rule: every implementation runs the same sequence of online steps (one pattern per
participant per step, in the given order) and returns the same winners; they differ in cost and
in float rounding only. The tests hold each fast one against the plain step-by-step rule
(``tests/test_som.py``).

* ``online``: the weights updated every step, every unit: the fused kernel of :mod:`.som_online`
  for the Kohonen rules, :func:`fit_plain` (:meth:`SOM.step` once per step, the plain rule, on any
  device and dtype) for any other;
* ``factored`` (:mod:`.som_factored`): never touches the weights while training; a step costs
  the neighbourhood times the number of patterns, independent of the input size;
* ``windowed`` (:mod:`.som_windowed`): the factored form per participant, touching only its own
  neighbourhood window of a 2-D map; CPU, unsupervised.
* ``repeated`` (:mod:`.som_repeated`): one labelled pattern presented ``T`` times with a constant
  rate and a neighbourhood that is the forced winner alone: the closed form of those ``T`` steps,
  one update of one row.

A trainer is ``fit(som, X (P, N, in), order (P, T), labels (P, N) | None, steps, **options) ->
winners (P, T)``, where ``steps`` iterates over the ``T`` step numbers (a progress bar may wrap
it). :func:`register` adds one; ``method='auto'`` takes the first of :data:`AUTO` whose
``suits`` (and ``applies``, given the pattern order) accepts the call.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch

from . import monitor


@dataclass(frozen=True)
class Trainer:
    """An implementation of the online rule: ``fit`` trains; ``refuse(som, X, labels, options)``
    says why it cannot train this call (``None`` if it can); ``suits`` says whether ``auto`` may
    pick it (and ``applies``, when given, that it holds for the call's pattern order); ``options``
    the keyword arguments of :meth:`SOM.fit` it reads."""

    name: str
    fit: Callable
    refuse: Callable = lambda som, X, labels, options: None
    suits: Callable = lambda som, X, labels: False
    options: tuple[str, ...] = ()
    # ``applies(som, X, order, labels)``: why this implementation would not give the plain rule's
    # steps for this pattern order (``None`` if it does); for a form the order decides (``repeated``)
    applies: Callable | None = None
    # several maps in one loop (``nn.som.fit_together``): ``fit_many([(som, X, order, labels, parts)])
    # -> [winners]``, each map's numbers those of its own ``fit``; None: one map at a time
    fit_many: Callable | None = None


TRAINERS: dict[str, Trainer] = {}
AUTO: list[str] = []  # the order in which method='auto' tries the trainers


def register(trainer: Trainer, auto: int | None = None) -> Trainer:
    """Add ``trainer`` (replacing one of the same name); ``auto`` is its place in :data:`AUTO`."""
    TRAINERS[trainer.name] = trainer
    if trainer.name in AUTO:
        AUTO.remove(trainer.name)
    if auto is not None:
        AUTO.insert(auto, trainer.name)
    return trainer


def _fits(tr: Trainer, som, X, labels, order) -> bool:
    if tr.applies is not None and order is None:
        return False
    return tr.suits(som, X, labels) and (tr.applies is None or tr.applies(som, X, order, labels) is None)


def choose(som, X: torch.Tensor, labels: torch.Tensor | None, method: str, options: dict,
           order: torch.Tensor | None = None) -> Trainer:
    """The trainer for ``method`` (or the first suitable one for ``'auto'``, given the pattern
    ``order`` ``(P, T)`` when one is passed); a ``ValueError`` if it cannot train this call or
    does not read one of ``options``."""
    if method == "auto":
        method = next(n for n in AUTO if _fits(TRAINERS[n], som, X, labels, order))
    if method not in TRAINERS:
        raise ValueError(f"method must be 'auto' or one of {sorted(TRAINERS)}, got {method!r}")
    tr = TRAINERS[method]
    extra = sorted(k for k, v in options.items() if v is not None and k not in tr.options)
    if extra:
        raise ValueError(f"method={method!r} takes no {', '.join(extra)}")
    why = tr.refuse(som, X, labels, options)
    if not why and tr.applies is not None:
        why = "needs the pattern order" if order is None else tr.applies(som, X, order, labels)
    if why:
        raise ValueError(f"method={method!r} {why}")
    return tr


# ------------------------------------------------------------------ the three implementations
def curve(som, T: int) -> monitor.Curve | None:
    """The running training curve of a fit of ``T`` steps: the mean distance of the presented
    patterns to their winners (or labelled units) before each step's change; None when no reader
    listens (:mod:`.monitor`), so an unwatched fit measures nothing."""
    if not monitor.active():
        return None
    what = "label" if som.supervised else "winner"
    return monitor.Curve(f"train/som/{som.name or 'som'}/{what}_distance", T, offset=int(som.steps))


def _fit_online(som, X, order, labels, steps, **_) -> torch.Tensor:
    """Every unit updated at every presentation: the fused kernel of :mod:`.som_online` for the
    Kohonen rules, otherwise one :meth:`SOM.step` per step (the plain rule)."""
    from . import som_online

    if som.weight.device.type != "meta" and som_online.supports(som.rule):
        return som_online.fit_online(som, X, order, labels, steps)
    return fit_plain(som, X, order, labels, steps)


def fit_plain(som, X, order, labels, steps=None) -> torch.Tensor:
    """The plain rule, the reference of every other implementation: one :meth:`SOM.step` per step."""
    p = torch.arange(som.participants, device=order.device)
    winners = torch.empty_like(order)
    steps = range(order.shape[1]) if steps is None else steps
    watch = curve(som, order.shape[1])
    for t in steps:
        s = order[:, t]
        x, w = X[p, s], None if labels is None else labels[p, s]
        if watch is not None:
            d2 = som.distances(x.unsqueeze(1))[:, 0]  # (P, U)
            watch.add(t, (d2.min(-1).values if w is None else d2[p, w]).sqrt().mean())
        winners[:, t] = som.step(x, w)
    return winners


def _rates_below_one(som) -> bool:
    return max(som.rule.eta0, som.rule.eta1) < 1


def _refuse_factored(som, X, labels, options):
    if som.weight.device.type == "meta":
        return "needs the weights' values; on the meta device use 'online'"
    if not _rates_below_one(som):
        return "needs learning rates below 1 (a unit may not jump onto a pattern)"
    return None


def _refuse_windowed(som, X, labels, options):
    if labels is not None:
        return "trains unsupervised maps; use 'factored' with labels"
    return _refuse_factored(som, X, labels, options)


def _fit_factored(som, X, order, labels, steps, **_):
    from .som_factored import fit_factored

    return fit_factored(som, X, order, labels, steps)


def _shared(X):
    """One pattern set for all participants (an expanded view): the windowed factors keep one copy."""
    return X[0] if X.dim() == 3 and X.shape[0] > 0 and X.stride(0) == 0 else X


def _fit_windowed(som, X, order, labels, steps, parts=None, **_):
    from .som_windowed import fit_windowed

    return fit_windowed(som, _shared(X), order, parts)


def _fit_windowed_many(jobs):
    from .som_windowed import fit_windowed_many

    return fit_windowed_many([(som, _shared(X), order, parts) for som, X, order, labels, parts in jobs])


def _applies_repeated(som, X, order, labels):
    from .som_repeated import applies

    return applies(som, X, order, labels)


def _fit_repeated(som, X, order, labels, steps, **_):
    from .som_repeated import fit_repeated

    return fit_repeated(som, X, order, labels, steps)


register(Trainer("online", _fit_online, suits=lambda som, X, labels: True), auto=0)
register(Trainer("factored", _fit_factored, _refuse_factored,
                 suits=lambda som, X, labels: (X.shape[1] < som.n_in and _rates_below_one(som)
                                               and som.weight.device.type != "meta")), auto=0)
register(Trainer("windowed", _fit_windowed, _refuse_windowed, options=("parts",), fit_many=_fit_windowed_many))
register(Trainer("repeated", _fit_repeated, suits=lambda som, X, labels: labels is not None,
                 applies=_applies_repeated), auto=0)
