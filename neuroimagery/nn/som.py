"""Kohonen self-organising maps (thesis 4.3.2, eq. 4.5-4.6; supervised form eq. 6.7-6.8,
6.14-6.16; bidirectional supervised SOM of chapter 7).

Weights ``(P, units, in)``: row ``k`` of participant ``p`` is unit ``k``'s prototype. Training is
online (one pattern per participant per iteration, as in the thesis's algorithm) and batched over
participants. :meth:`SOM.fit` trains by one of the forms of that online rule registered for a
SOM (:mod:`neuroimagery.nn.forms`; :func:`fit_plain` is the reference of them all):
``method='online'`` (every unit updated at every
presentation: the fused kernel of :mod:`neuroimagery.nn.som_online` for the Kohonen rules, one
:meth:`SOM.step` per step otherwise), ``'factored'`` (:mod:`~neuroimagery.nn.som_factored`: the weights
never touched while training) or ``'windowed'`` (:mod:`~neuroimagery.nn.som_windowed`: the
factored form per participant neighbourhood window, unsupervised 2-D maps, CPU). They give the
same winners and the same weights up to float rounding (``tests/test_som.py``).

``method='auto'`` picks ``repeated`` (:mod:`~neuroimagery.nn.som_repeated`) when one labelled
pattern is presented at every step with a constant rate and a neighbourhood that is the forced
winner alone (the closed form of those steps), else ``factored`` when ``N < n_in`` and the
initial and final learning rates (``eta``, ``eta_final``) are below 1, ``online`` otherwise; ``N`` is the number of rows of the
``patterns`` given to :meth:`SOM.fit`, repeated patterns included (not the number of distinct
patterns). It never picks ``windowed``, and picks ``online`` on the ``meta`` device (the
factored form chooses its work by the values it computes).
"""
from __future__ import annotations

from typing import Sequence

from types import SimpleNamespace

import torch
from torch import nn

from . import monitor, seeding
from .functional import (as_batched, check_floating, check_rate, check_tensor, checks_enabled, grid_coords,
                         participants_weight, squared_norms)
from . import forms
from .change import as_change
from .readout import Readouts
from .rules import Kohonen, SupervisedKohonen

NORM_ROWS = 256  # prototypes squared and summed at a time by SOM.prototype_norms (the temporary stays small)
ORDER_STREAM = 1  # stream of participant_generators(seed, P, stream) a SOM built from a seed draws fit() orders from


class SOM(Readouts, nn.Module):
    """A (supervised) Kohonen map with max-normalised read-out.

    Args:
        shape: grid of the map, ``(n,)`` or ``(rows, cols)``.
        n_in: input size.
        participants / generators / seed: independent weights per participant, U[init] at start.
            A map built from ``seed`` (no ``generators``) keeps it in ``seed`` and draws the
            pattern order of :meth:`fit` from it when given neither generators nor an order.
        eta, sigma, eta_final, sigma_final, iterations: decay schedule of eq. 4.5 (``sigma`` in grid
            units; default: half the larger side).
        supervised: forced winners and unit-sum normalisation (eq. 6.7-6.8) instead of BMU search.
        input_scale: supervised maps only: ``'auto'`` (default: each input divided by its sum, the
            weights' scale, in training and read-out alike), ``'sum'`` or ``'raw'`` (inputs as
            given); see :class:`~.rules.SupervisedKohonen`.
        readout: ``'dot'`` (``y = W x``, eq. 4.4) or ``'distance'`` (``y = -|x - w|``, shifted to be
            positive), both normalised by their maximum (eq. 4.6).
        name: in messages and training-curve tags (default ``SOM(rows x cols, in=n)``).

    The read-out computes in the input's dtype; training (:meth:`step`, :meth:`fit`) casts the
    patterns to the weights' dtype, so the weights keep theirs.
    """

    def __init__(self, shape: Sequence[int], n_in: int, participants: int = 1,
                 generators: Sequence[torch.Generator] | None = None, seed: int = 0,
                 init: tuple[float, float] = (0.0, 0.1), eta: float = 0.1, sigma: float | None = None,
                 eta_final: float = 0.01, sigma_final: float = 0.5, iterations: int = 10_000,
                 supervised: bool = False, readout: str = "dot", name: str = "", input_scale: str = "auto") -> None:
        super().__init__()
        self.shape = tuple(int(s) for s in shape)
        name = name or f"SOM({'x'.join(map(str, self.shape))}, in={n_in})"
        if len(self.shape) not in (1, 2) or min(self.shape) < 1:
            raise ValueError(f"SOM {name!r}: shape must be (n,) or (rows, cols), got {shape}")
        if n_in < 1:
            raise ValueError(f"SOM {name!r}: n_in must be >= 1, got {n_in}")
        if readout not in ("dot", "distance"):
            raise ValueError(f"readout must be 'dot' or 'distance', got {readout!r}")
        self.n_in, self.name, self.readout, self.supervised = int(n_in), name, readout, bool(supervised)
        self.seed = int(seed) if generators is None else None
        # made from ``seed`` by the first fit() given neither generators nor an order
        self.order_generators: list[torch.Generator] | None = None
        if generators is None:
            generators = seeding.participant_generators(seed, participants)
        units = 1
        for s in self.shape:
            units *= s
        self.units = units
        sigma = max(self.shape) / 2.0 if sigma is None else sigma
        rule_cls = SupervisedKohonen if supervised else Kohonen
        if supervised:
            self.rule = SupervisedKohonen(eta, sigma, iterations, eta_final, sigma_final, input_scale=input_scale)
        else:
            if input_scale not in ("auto", "raw"):
                raise ValueError(f"SOM {name!r}: input_scale={input_scale!r} applies to supervised maps only")
            self.rule = rule_cls(eta, sigma, iterations, eta_final, sigma_final)
        self.register_buffer("grid", grid_coords(self.shape))
        self.register_buffer("weight", seeding.uniform(generators, (units, self.n_in), float(init[0]), float(init[1])))
        self.register_buffer("steps", torch.zeros((), dtype=torch.long))
        self.learnt_factors: dict | None = None  # what the last fit formed the weights from (windowed)

    @property
    def participants(self) -> int:
        return self.weight.shape[0]

    # ------------------------------------------------------------------ read-out
    block_kind = "SOM"

    def _weight_for(self, xb: torch.Tensor, given) -> torch.Tensor:
        return participants_weight(f"SOM {self.name!r}", self.weight, xb, given)

    def distances(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """Squared Euclidean distance of every input ``(P, B, in)`` to every unit -> ``(P, B, units)``
        (the input scaled as the rule sees it; ``checked``: see :meth:`net`)."""
        xb, _ = self.batched(x, self.n_in, checked)
        xb = self.rule.scale_input(xb)
        w = self._weight_for(xb, x.shape)
        d = squared_norms(w).unsqueeze(1) - 2 * torch.bmm(xb, w.transpose(1, 2)) + (xb * xb).sum(-1, keepdim=True)
        return d.clamp_min(0)

    def bmu(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """Best-matching unit (Euclidean) of each input -> long ``(P, B)``."""
        return self.distances(x, checked=checked).argmin(-1)

    def net(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """``W x`` ``(P, B, units)`` of the input as given (eq. 4.4: no input scaling, no
        normalisation), e.g. for the unit of the largest product. Shapes are checked once per
        configuration, values at every call unless ``checked`` (the caller checked the batch)."""
        xb, squeeze = self.batched(x, self.n_in, checked)
        y = torch.bmm(xb, self._weight_for(xb, x.shape).transpose(1, 2))
        return (y[0] if x.dim() == 2 else y[0, 0]) if squeeze else y

    def forward(self, x: torch.Tensor, *, checked: bool = False) -> torch.Tensor:
        """Max-normalised read-out (eq. 4.4 + 4.6), shape ``(P, B, *shape)`` (or without P for 2-D input)."""
        xb, squeeze = self.batched(x, self.n_in, checked)
        xb = self.rule.scale_input(xb)
        if self.readout == "dot":
            y = torch.bmm(xb, self._weight_for(xb, x.shape).transpose(1, 2))
        else:
            d = self.distances(xb, checked=True).sqrt()
            y = d.max(-1, keepdim=True).values - d
        y = y / y.max(-1, keepdim=True).values.clamp_min(1e-12)
        y = y.reshape(*y.shape[:-1], *self.shape)
        if squeeze:
            return y[0] if x.dim() == 2 else y[0, 0]
        return y

    def distances_of(self, participant: int, x: torch.Tensor) -> torch.Tensor:
        """Participant ``participant``'s squared distances ``(units,)`` of one pattern ``x`` ``(in,)``
        (scaled as the rule sees it) to every prototype, summed directly, ``sum_i (x_i - w_ki)^2``
        (the plain form of :meth:`distances`)."""
        check_tensor(f"input of SOM {self.name!r}", x, (self.n_in,))
        return ((self.rule.scale_input(x) - self.weight[participant]) ** 2).sum(-1)

    def prototype_norms(self, lo: int = 0, hi: int | None = None) -> torch.Tensor:
        """Squared norms ``(P, units)`` of the prototypes' inputs ``lo..hi`` (all by default), made
        once per version of the weights."""
        hi = self.n_in if hi is None else hi
        key = (self.weights_version(), lo, hi)
        cache = getattr(self, "_norms", {})
        if key not in cache:
            cache = {k: v for k, v in cache.items() if k[0] == key[0]}
            w = self.weight[..., lo:hi]  # a view: each row's sum over its own inputs, NORM_ROWS rows at a time
            norms = w.new_empty(w.shape[:-1])
            for p in range(w.shape[0]):
                for a in range(0, w.shape[1], NORM_ROWS):
                    block = w[p, a:a + NORM_ROWS]
                    norms[p, a:a + NORM_ROWS] = (block * block).sum(-1)
            cache[key] = norms
            self._norms = cache
        return cache[key]

    def part_products(self, codes: torch.Tensor, lo: int = 0, hi: int | None = None) -> torch.Tensor:
        """``W[:, :, lo:hi] c`` ``(P, K, units)`` of each code ``c`` of ``codes`` ``(K, hi - lo)``,
        shared by every participant: the products of the inputs ``lo..hi`` alone (a distance to
        an input made of parts is a sum of such products)."""
        hi = self.n_in if hi is None else hi
        check_tensor(f"codes of SOM {self.name!r}", codes, (hi - lo,))
        if codes.dim() != 2:
            raise ValueError(f"SOM {self.name!r}: codes must be (K, {hi - lo}), got {tuple(codes.shape)}")
        return torch.einsum("pui,ki->pku", self.weight[..., lo:hi], codes)

    def part_distances(self, x: torch.Tensor, lo: int = 0, hi: int | None = None, participant: int = 0,
                       *, checked: bool = False) -> torch.Tensor:
        """``|w_k[lo:hi]|^2 - 2 w_k[lo:hi] . x`` ``(units,)`` of participant ``participant`` for one
        pattern ``x`` ``(hi - lo,)``: the squared distance of ``x`` to inputs ``lo..hi`` of each
        prototype up to ``x``'s own norm (the same nearest unit), the norms made once per version
        of the weights. ``checked``: the caller has checked ``x``'s values."""
        hi = self.n_in if hi is None else hi
        if x.shape != (hi - lo,):
            raise ValueError(f"SOM {self.name!r}: a pattern of inputs {lo}..{hi} must have shape ({hi - lo},), "
                             f"got {tuple(x.shape)}")
        if not checked:
            check_tensor(f"pattern of SOM {self.name!r}", x)
        return self.prototype_norms(lo, hi)[participant] - 2.0 * (self.weight[participant, :, lo:hi] @ x)

    def prototypes(self, units: torch.Tensor, lo: int = 0, hi: int | None = None) -> torch.Tensor:
        """A copy of inputs ``lo..hi`` of the prototypes of ``units`` ``(P, ...)`` (one unit index
        per participant row) -> ``(P, ..., hi - lo)``."""
        hi = self.n_in if hi is None else hi
        units = torch.as_tensor(units, dtype=torch.long)
        p = torch.arange(self.participants).reshape(-1, *([1] * (units.dim() - 1)))
        return self.weight[p, units, lo:hi].clone()

    # ------------------------------------------------------------------ learning
    @torch.no_grad()
    def step(self, x: torch.Tensor, winner: torch.Tensor | None = None) -> torch.Tensor:
        """One online step (eq. 4.5) with one pattern per participant ``x`` ``(P, in)``.

        ``winner`` ``(P,)`` forces the winning unit (supervised, eq. 6.7); otherwise the BMU is
        used. Returns the winners. In ``eval()`` mode the weights are left unchanged (the winners
        are still returned).
        """
        check_tensor("x", x, (self.n_in,))
        check_floating(f"x of SOM {self.name!r}", x)
        xb = self.rule.scale_input(x.reshape(self.participants, 1, self.n_in).to(self.weight.dtype))
        if winner is None:
            if self.supervised:
                raise ValueError(f"SOM {self.name!r} is supervised: step() needs the winner")
            winner = self.bmu(xb)[:, 0]
        if self.training:
            # the rule computes the change (the Kohonen contract of every rule: delta at the weights),
            # the map applies it
            change = self.rule.delta(self.weight, pre=xb, bmu=winner, grid=self.grid, t=self.steps)
            as_change(self.weight, change).apply_(self.weight)
            self.steps += 1
        return winner

    @torch.no_grad()
    def fit(self, patterns: torch.Tensor, iterations: int | None = None, labels: torch.Tensor | None = None,
            generators: Sequence[torch.Generator] | None = None, order: torch.Tensor | None = None,
            method: str = "auto", progress: bool = False, parts: Sequence[int] | None = None,
            _together: list | None = None) -> torch.Tensor:
        """Train on ``patterns`` (``(N, in)`` shared, or ``(P, N, in)`` per participant).

        Each iteration every participant draws one pattern at random (its own generator, or the
        given ``order`` ``(P, iterations)`` of indices). Without either, a map built from a seed
        draws from its own generators, ``participant_generators(seed, P, ORDER_STREAM)`` made at
        the first such call and carried on by the next ones (kept in ``order_generators``; not
        part of the ``state_dict``). ``labels`` ``(N,)`` or ``(P, N)`` are the
        forced winners of a supervised map. In ``train()`` mode, returns the winners
        ``(P, iterations)``. In ``eval()`` mode nothing is trained: the arguments are checked, the
        pattern order is drawn (or taken from ``order``) and returned, ``(P, iterations)`` pattern
        indices, not winners.
        """
        if method != "auto" and method not in forms.names(self):
            raise ValueError(f"method must be 'auto' or one of {forms.names(self)}, got {method!r}")
        check_tensor("patterns", patterns, (self.n_in,))
        P = self.participants
        X = self.rule.scale_input(patterns.to(self.weight.dtype))
        X = X.unsqueeze(0).expand(P, -1, -1) if X.dim() == 2 else X
        if X.dim() != 3 or X.shape[0] != P:
            raise ValueError(f"patterns must be (N, {self.n_in}) or ({P}, N, {self.n_in}), got {tuple(patterns.shape)}")
        N = X.shape[1]
        if self.supervised and labels is None:
            raise ValueError(f"SOM {self.name!r} is supervised: fit() needs labels")
        dev = self.weight.device
        if labels is not None:
            labels = torch.as_tensor(labels, dtype=torch.long, device=dev)
            labels = labels.unsqueeze(0).expand(P, -1) if labels.dim() == 1 else labels
            if labels.shape != (P, N):
                raise ValueError(f"labels must be (N,) or (P, N) with N={N}, got {tuple(labels.shape)}")
            if checks_enabled(labels) and (labels.min() < 0 or labels.max() >= self.units):
                raise ValueError(f"labels must index units 0..{self.units - 1}")
        T = self.rule.iterations if iterations is None else int(iterations)
        if T < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        if order is None:
            if generators is None:
                generators = self._order_generators()
            if len(generators) != P:
                raise ValueError(f"fit(): {len(generators)} generators for {P} participants")
            order = seeding.randint(generators, N, (T,))
        order = torch.as_tensor(order, dtype=torch.long, device=dev)
        if order.shape != (P, T):
            raise ValueError(f"order must have shape ({P}, {T}), got {tuple(order.shape)}")
        if not self.training:
            return order
        trainer = choose(self, X, labels, method, {"parts": parts}, order)
        self.learnt_factors = None
        it = range(T)
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc=f"SOM {self.name}", leave=False)
        if _together is not None:  # fit_together: the map's checked call, trained with the others
            _together.append((self, trainer, X, order, labels, parts, it))
            return None
        return self._finish(X, _run(trainer, self, X, order, labels, it, parts), order)

    def _finish(self, X: torch.Tensor, winners: torch.Tensor, order: torch.Tensor) -> torch.Tensor:
        if monitor.active():  # the trained map's final state, at its own step count
            tag = f"train/som/{self.name or 'som'}"
            if not self.supervised and winners is not None:
                winner_changes(tag, order, winners, int(self.steps) - order.shape[1])
            monitor.record(f"{tag}/quantisation_error_final", self.quantization_error(X).mean(), int(self.steps))
            if self.units > 1:
                monitor.record(f"{tag}/topographic_error_final", self.topographic_error(X).mean(), int(self.steps))
        return winners

    def _order_generators(self) -> list[torch.Generator]:
        if self.order_generators is None:
            if self.seed is None:
                raise ValueError(f"SOM {self.name!r} was built from explicit generators: fit() needs generators "
                                 "(one per participant) or an explicit order")
            self.order_generators = seeding.participant_generators(self.seed, self.participants, ORDER_STREAM)
        return self.order_generators

    def quantization_error(self, patterns: torch.Tensor) -> torch.Tensor:
        """Mean distance of each participant's patterns to their BMU prototype -> ``(P,)``."""
        X = patterns.unsqueeze(0).expand(self.participants, -1, -1) if patterns.dim() == 2 else patterns
        return self.distances(X).min(-1).values.sqrt().mean(-1)

    def topographic_error(self, patterns: torch.Tensor) -> torch.Tensor:
        """Share of patterns whose two best units are not grid neighbours -> ``(P,)``."""
        X = patterns.unsqueeze(0).expand(self.participants, -1, -1) if patterns.dim() == 2 else patterns
        two = self.distances(X).topk(2, dim=-1, largest=False).indices  # (P, N, 2)
        d = (self.grid[two[..., 0]] - self.grid[two[..., 1]]).abs().max(-1).values
        return (d > 1).float().mean(-1)

    def reset_state(self) -> None:
        """SOMs keep no activity between calls."""

    def extra_repr(self) -> str:
        return f"name={self.name!r}, shape={self.shape}, in={self.n_in}, P={self.participants}, supervised={self.supervised}"


def _call(X, order, labels, steps=None, parts=None) -> SimpleNamespace:
    """A fit's arguments as its forms read them."""
    return SimpleNamespace(X=X, order=order, labels=labels, steps=steps, options={"parts": parts})


def _run(form, som, X, order, labels, steps, parts):
    som.learnt_factors = None
    return form.run(som, som.rule, _call(X, order, labels, steps, parts))


def choose(som, X: torch.Tensor, labels: torch.Tensor | None, method: str, options: dict,
           order: torch.Tensor | None = None) -> forms.Form:
    """The form that trains ``som`` for ``method`` (for ``'auto'``, the first that suits the call,
    given the pattern ``order`` ``(P, T)`` when one is passed); a ``ValueError`` if it cannot
    train this call or does not read one of ``options``."""
    call = SimpleNamespace(X=X, order=order, labels=labels, steps=None, options=options)
    form = forms.choose(som, som.rule, call, method)
    if form is None:
        raise ValueError(f"no registered form trains SOM {som.name!r} with {type(som.rule).__name__}")
    return form


def winner_changes(tag: str, order: torch.Tensor, winners: torch.Tensor, offset: int, points: int = 100) -> None:
    """The training curve every form of a fit has, from its winners alone: the share of
    presentations whose winner differs from the winner of the same pattern's previous presentation
    (a pattern's first presentation does not count), over the participants, about ``points``
    stretches of the fit (``tag/winner_changes``). It falls as the map settles."""
    P, T = order.shape
    key = (torch.arange(P, device=order.device).unsqueeze(1) * (int(order.max()) + 1) + order).reshape(-1)
    idx = torch.argsort(key * T + torch.arange(T, device=order.device).repeat(P), stable=True)
    k, w = key[idx], winners.reshape(-1)[idx]
    again = torch.zeros(P * T, dtype=torch.bool, device=order.device)
    changed = torch.zeros(P * T, dtype=torch.float64, device=order.device)
    same = k[1:] == k[:-1]  # the same pattern of the same participant, presented again
    again[idx[1:][same]] = True
    changed[idx[1:][same]] = (w[1:][same] != w[:-1][same]).double()
    stride = max(1, T // points)
    again, changed = again.view(P, T), changed.view(P, T)
    for lo in range(0, T, stride):
        n = int(again[:, lo:lo + stride].sum())
        if n:
            monitor.record(f"{tag}/winner_changes", float(changed[:, lo:lo + stride].sum()) / n,
                           offset + min(lo + stride, T))


def curve(som, T: int) -> monitor.Curve | None:
    """The running training curve of a fit of ``T`` steps: the mean distance of the presented
    patterns to their winners (or labelled units) before each step's change; None when no reader
    listens (:mod:`.monitor`), so an unwatched fit measures nothing."""
    if not monitor.active():
        return None
    what = "label" if som.supervised else "winner"
    return monitor.Curve(f"train/som/{som.name or 'som'}/{what}_distance", T, offset=int(som.steps))


def fit_plain(som, X, order, labels, steps=None) -> torch.Tensor:
    """The plain rule, the reference of every other form: one :meth:`SOM.step` per step."""
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


@torch.no_grad()
def fit_together(fits: Sequence[tuple[SOM, dict]]) -> list[torch.Tensor]:
    """``som.fit(**kwargs)`` for each ``(som, kwargs)`` of ``fits``, with the maps whose chosen
    form can train several maps in one loop (``Form.run_many``, e.g. ``windowed``)
    trained together: each map's arguments are checked as by its own :meth:`SOM.fit`, and it
    gets the winners and weights its own fit would give (every participant's arithmetic is its
    own). Returns what each ``fit`` returns."""
    out: list = [None] * len(fits)
    queued: list = []
    for i, (som, kw) in enumerate(fits):
        n = len(queued)
        res = som.fit(**kw, _together=queued)
        if len(queued) == n:  # nothing to train (eval mode): the order
            out[i] = res
        else:
            queued[-1] = (i, *queued[-1])
    groups: dict = {}
    for job in queued:
        tr = job[2]
        groups.setdefault(tr.name if tr.run_many is not None else ("alone", job[0]), []).append(job)
    for jobs in groups.values():
        tr = jobs[0][2]
        if tr.run_many is not None and len(jobs) > 1:
            wins = tr.run_many([(som, X, order, labels, parts) for _, som, _, X, order, labels, parts, _ in jobs])
        else:
            wins = [_run(tr, som, X, order, labels, it, parts) for _, som, _, X, order, labels, parts, it in jobs]
        for (i, som, _, X, order, *_), w in zip(jobs, wins):
            out[i] = som._finish(X, w, order)
    return out


class BidirectionalSOM(nn.Module):
    """Supervised SOM over paired patterns that runs both ways (chapter 7, connection C3).

    Each unit keeps a prototype of an *input* pattern ``a`` (size ``n_a``) and of an *output*
    pattern ``b`` (size ``n_b``). Training presents the concatenation ``[a, b]``; the winner is
    forced to the pair's label if one is given, otherwise it is the best match. Afterwards
    ``forward(a)`` finds the unit whose ``a``-prototype matches best and returns its
    ``b``-prototype; ``backward(b)`` does the reverse, which is how an action (``b``) is turned
    into the image of its outcome (``a``).
    """

    def __init__(self, units: int, n_a: int, n_b: int, participants: int = 1,
                 generators: Sequence[torch.Generator] | None = None, seed: int = 0, eta: float = 0.1,
                 sigma: float = 0.5, iterations: int = 1000, eta_final: float | None = None,
                 sigma_final: float | None = None, name: str = "") -> None:
        super().__init__()
        self.n_a, self.n_b, self.name = int(n_a), int(n_b), name
        check_rate("eta", eta, open_low=True)
        self.som = SOM((units,), self.n_a + self.n_b, participants, generators, seed, (0.0, 0.1), eta, sigma,
                       eta if eta_final is None else eta_final, sigma if sigma_final is None else sigma_final,
                       iterations, supervised=False, name=name)

    @property
    def weight(self) -> torch.Tensor:
        return self.som.weight

    def fit(self, a: torch.Tensor, b: torch.Tensor, labels: torch.Tensor | None = None, **kw) -> torch.Tensor:
        """Train on paired patterns ``a`` ``(.., N, n_a)`` and ``b`` ``(.., N, n_b)``."""
        check_tensor("a", a, (self.n_a,))
        check_tensor("b", b, (self.n_b,))
        if a.shape[:-1] != b.shape[:-1]:
            raise ValueError(f"a and b must pair up: {tuple(a.shape)} vs {tuple(b.shape)}")
        X = torch.cat([a, b], dim=-1)
        if labels is not None:
            self.som.supervised = True
            self.som.rule.normalise = False  # prototypes are images, not weight distributions
        return self.som.fit(X, labels=labels, **kw)

    def _match(self, x: torch.Tensor, lo: int, hi: int) -> torch.Tensor:
        xb, _ = as_batched(x, hi - lo, f"pattern of {self.name!r}")
        w = participants_weight(f"BidirectionalSOM {self.name!r}", self.som.weight[..., lo:hi], xb, x.shape)
        d = (w * w).sum(-1).unsqueeze(1) - 2 * torch.bmm(xb, w.transpose(1, 2))
        return d.argmin(-1)  # (P, B)

    def _prototypes(self, units: torch.Tensor, lo: int, hi: int) -> torch.Tensor:
        w = self.som.weight[..., lo:hi]
        return torch.stack([w[p, units[p]] for p in range(w.shape[0])])

    def forward(self, a: torch.Tensor) -> torch.Tensor:
        """``a -> b``: output prototype of the unit that best matches ``a`` ``(P, B, n_a)``."""
        return self._prototypes(self._match(a, 0, self.n_a), self.n_a, self.n_a + self.n_b)

    def backward(self, b: torch.Tensor) -> torch.Tensor:
        """``b -> a``: the input pattern (mental image) associated with ``b`` ``(P, B, n_b)``."""
        return self._prototypes(self._match(b, self.n_a, self.n_a + self.n_b), 0, self.n_a)

    def reset_state(self) -> None:
        pass
