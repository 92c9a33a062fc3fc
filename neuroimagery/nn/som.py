"""Kohonen self-organising maps (thesis 4.3.2, eq. 4.5-4.6; supervised form eq. 6.7-6.8,
6.14-6.16; bidirectional supervised SOM of chapter 7).

Weights ``(P, units, in)``: row ``k`` of participant ``p`` is unit ``k``'s prototype. Training is
online (one pattern per participant per iteration, as in the thesis's algorithm) and batched over
participants. Two exact implementations of the same online rule are offered:

* ``method='online'`` updates the weight matrix at every step (cost ``units x in`` per step);
* ``method='factored'`` never touches the weights while training. Every weight vector stays a
  scaled combination ``w_k = c_k (w0_k + sum_n R_kn x_n)`` of its initial value and the ``N``
  training patterns, so the step ``w_k <- (1 - a_k) w_k + a_k x_s`` only rescales ``c_k`` and
  adds to ``R_ks``; distances come from maintained dot products with the patterns and closed-form
  norms. A step costs ``(units in the neighbourhood) x N``, independent of the input size, and
  the weights are formed once at the end. Same sequence of winners, same weights up to float
  rounding (see ``tests/test_som.py``).

* ``method='windowed'`` (unsupervised 2-D maps) is the factored form again, but each participant
  touches only the square of units its own truncated neighbourhood reaches, so batching many
  participants does not widen the region updated at each step (:func:`fit_windowed`).

``method='auto'`` picks ``factored`` when ``N < n_in`` and the initial and final learning rates
(``eta``, ``eta_final``) are below 1, ``online`` otherwise; ``N`` is the number of rows of the
``patterns`` given to :meth:`SOM.fit`, repeated patterns included (not the number of distinct
patterns). It never picks ``windowed``.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from torch import nn

from . import seeding
from .functional import as_batched, check_rate, check_tensor
from .rules import Kohonen, SupervisedKohonen


def grid_coords(shape: Sequence[int]) -> torch.Tensor:
    """Integer grid coordinates ``(units, D)`` of a 1-D or 2-D map."""
    axes = [torch.arange(int(n), dtype=torch.float32) for n in shape]
    g = torch.meshgrid(*axes, indexing="ij")
    return torch.stack([x.reshape(-1) for x in g], dim=-1)


def squared_norms(w: torch.Tensor, rows: int = 256) -> torch.Tensor:
    """``(w * w).sum(-1)`` computed a block of rows at a time: the same numbers (each row's sum
    is its own reduction) without a temporary the size of ``w``."""
    flat = w.reshape(-1, w.shape[-1])
    return torch.cat([(b * b).sum(-1) for b in flat.split(rows)]).reshape(w.shape[:-1])


class SOM(nn.Module):
    """A (supervised) Kohonen map with max-normalised read-out.

    Args:
        shape: grid of the map, ``(n,)`` or ``(rows, cols)``.
        n_in: input size.
        participants / generators / seed: independent weights per participant, U[init] at start.
        eta, sigma, eta_final, sigma_final, iterations: decay schedule of eq. 4.5 (``sigma`` in grid
            units; default: half the larger side).
        supervised: forced winners and unit-sum normalisation (eq. 6.7-6.8) instead of BMU search.
        readout: ``'dot'`` (``y = W x``, eq. 4.4) or ``'distance'`` (``y = -|x - w|``, shifted to be
            positive), both normalised by their maximum (eq. 4.6).
    """

    def __init__(self, shape: Sequence[int], n_in: int, participants: int = 1,
                 generators: Sequence[torch.Generator] | None = None, seed: int = 0,
                 init: tuple[float, float] = (0.0, 0.1), eta: float = 0.1, sigma: float | None = None,
                 eta_final: float = 0.01, sigma_final: float = 0.5, iterations: int = 10_000,
                 supervised: bool = False, readout: str = "dot", name: str = "") -> None:
        super().__init__()
        self.shape = tuple(int(s) for s in shape)
        if len(self.shape) not in (1, 2) or min(self.shape) < 1:
            raise ValueError(f"SOM {name!r}: shape must be (n,) or (rows, cols), got {shape}")
        if n_in < 1:
            raise ValueError(f"SOM {name!r}: n_in must be >= 1, got {n_in}")
        if readout not in ("dot", "distance"):
            raise ValueError(f"readout must be 'dot' or 'distance', got {readout!r}")
        self.n_in, self.name, self.readout, self.supervised = int(n_in), name, readout, bool(supervised)
        if generators is None:
            generators = seeding.participant_generators(seed, participants)
        units = 1
        for s in self.shape:
            units *= s
        self.units = units
        sigma = max(self.shape) / 2.0 if sigma is None else sigma
        rule_cls = SupervisedKohonen if supervised else Kohonen
        if supervised:
            self.rule = SupervisedKohonen(eta, sigma, iterations, eta_final, sigma_final)
        else:
            self.rule = rule_cls(eta, sigma, iterations, eta_final, sigma_final)
        self.register_buffer("grid", grid_coords(self.shape))
        self.register_buffer("weight", seeding.uniform(generators, (units, self.n_in), float(init[0]), float(init[1])))
        self.register_buffer("steps", torch.zeros((), dtype=torch.long))

    @property
    def participants(self) -> int:
        return self.weight.shape[0]

    # ------------------------------------------------------------------ read-out
    def distances(self, x: torch.Tensor) -> torch.Tensor:
        """Squared Euclidean distance of every input ``(P, B, in)`` to every unit -> ``(P, B, units)``."""
        xb, _ = as_batched(x, self.n_in, f"input of SOM {self.name!r}")
        w = self.weight
        d = squared_norms(w).unsqueeze(1) - 2 * torch.bmm(xb, w.transpose(1, 2)) + (xb * xb).sum(-1, keepdim=True)
        return d.clamp_min(0)

    def bmu(self, x: torch.Tensor) -> torch.Tensor:
        """Best-matching unit (Euclidean) of each input -> long ``(P, B)``."""
        return self.distances(x).argmin(-1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Max-normalised read-out (eq. 4.4 + 4.6), shape ``(P, B, *shape)`` (or without P for 2-D input)."""
        xb, squeeze = as_batched(x, self.n_in, f"input of SOM {self.name!r}")
        if self.readout == "dot":
            y = torch.bmm(xb, self.weight.transpose(1, 2))
        else:
            d = self.distances(xb).sqrt()
            y = d.max(-1, keepdim=True).values - d
        y = y / y.max(-1, keepdim=True).values.clamp_min(1e-12)
        y = y.reshape(*y.shape[:-1], *self.shape)
        if squeeze:
            return y[0] if x.dim() == 2 else y[0, 0]
        return y

    # ------------------------------------------------------------------ learning
    @torch.no_grad()
    def step(self, x: torch.Tensor, winner: torch.Tensor | None = None) -> torch.Tensor:
        """One online step (eq. 4.5) with one pattern per participant ``x`` ``(P, in)``.

        ``winner`` ``(P,)`` forces the winning unit (supervised, eq. 6.7); otherwise the BMU is
        used. Returns the winners. In ``eval()`` mode the weights are left unchanged (the winners
        are still returned).
        """
        check_tensor("x", x, (self.n_in,))
        xb = x.reshape(self.participants, 1, self.n_in)
        if winner is None:
            if self.supervised:
                raise ValueError(f"SOM {self.name!r} is supervised: step() needs the winner")
            winner = self.bmu(xb)[:, 0]
        if self.training:
            d = self.rule.delta(self.weight, pre=xb, bmu=winner, grid=self.grid, t=int(self.steps))
            self.weight.add_(d)
            self.steps += 1
        return winner

    @torch.no_grad()
    def fit(self, patterns: torch.Tensor, iterations: int | None = None, labels: torch.Tensor | None = None,
            generators: Sequence[torch.Generator] | None = None, order: torch.Tensor | None = None,
            method: str = "auto", progress: bool = False) -> torch.Tensor:
        """Train on ``patterns`` (``(N, in)`` shared, or ``(P, N, in)`` per participant).

        Each iteration every participant draws one pattern at random (its own generator, or the
        given ``order`` ``(P, iterations)`` of indices). ``labels`` ``(N,)`` or ``(P, N)`` are the
        forced winners of a supervised map. In ``train()`` mode, returns the winners
        ``(P, iterations)``. In ``eval()`` mode nothing is trained: the arguments are checked, the
        pattern order is drawn (or taken from ``order``) and returned, ``(P, iterations)`` pattern
        indices, not winners.
        """
        if method not in ("auto", "online", "factored", "windowed"):
            raise ValueError(f"method must be 'auto', 'online', 'factored' or 'windowed', got {method!r}")
        check_tensor("patterns", patterns, (self.n_in,))
        P = self.participants
        X = patterns.to(self.weight.dtype)
        X = X.unsqueeze(0).expand(P, -1, -1) if X.dim() == 2 else X
        if X.dim() != 3 or X.shape[0] != P:
            raise ValueError(f"patterns must be (N, {self.n_in}) or ({P}, N, {self.n_in}), got {tuple(patterns.shape)}")
        N = X.shape[1]
        if self.supervised and labels is None:
            raise ValueError(f"SOM {self.name!r} is supervised: fit() needs labels")
        if labels is not None:
            labels = torch.as_tensor(labels, dtype=torch.long)
            labels = labels.unsqueeze(0).expand(P, -1) if labels.dim() == 1 else labels
            if labels.shape != (P, N):
                raise ValueError(f"labels must be (N,) or (P, N) with N={N}, got {tuple(labels.shape)}")
            if labels.min() < 0 or labels.max() >= self.units:
                raise ValueError(f"labels must index units 0..{self.units - 1}")
        T = self.rule.iterations if iterations is None else int(iterations)
        if T < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        if order is None:
            if generators is None:
                raise ValueError("fit() needs generators (one per participant) or an explicit order")
            if len(generators) != P:
                raise ValueError(f"fit(): {len(generators)} generators for {P} participants")
            order = seeding.randint(generators, N, (T,))
        order = torch.as_tensor(order, dtype=torch.long)
        if order.shape != (P, T):
            raise ValueError(f"order must have shape ({P}, {T}), got {tuple(order.shape)}")
        if not self.training:
            return order
        if method == "auto":
            method = "factored" if N < self.n_in and max(self.rule.eta0, self.rule.eta1) < 1 else "online"
        if method == "factored" and max(self.rule.eta0, self.rule.eta1) >= 1:
            raise ValueError("method='factored' needs learning rates below 1 (a unit may not jump onto a pattern)")
        it = range(T)
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(it, desc=f"SOM {self.name}", leave=False)
        if method == "windowed":
            if labels is not None:
                raise ValueError("method='windowed' trains unsupervised maps; use 'factored' with labels")
            return fit_windowed(self, X, order)
        fn = self._fit_factored if method == "factored" else self._fit_online
        return fn(X, order, labels, it)

    def _fit_online(self, X, order, labels, it) -> torch.Tensor:
        P = self.participants
        p = torch.arange(P)
        winners = torch.empty_like(order)
        for t in it:
            s = order[:, t]
            x = X[p, s]
            w = None if labels is None else labels[p, s]
            winners[:, t] = self.step(x, w)
        return winners

    def _fit_factored(self, X, order, labels, it) -> torch.Tensor:
        """Exact online training without touching the weights (see the module docstring).

        Invariants, per participant and unit ``k`` (``W0`` the initial weights, ``x_n`` the patterns;
        ``Q`` and ``R`` are stored pattern-major):
        ``w_k = c_k (W0_k + sum_m R_km x_m)`` and ``w_k . x_n = c_k Q_kn`` with
        ``Q_kn = W0_k . x_n + sum_m R_km G_mn``, ``G = X X^T``. A step with rate ``a_k`` toward
        ``x_s`` sets ``c_k <- (1 - a_k) c_k``, ``R_ks += a_k / c_k``, ``Q_k += (a_k / c_k) G_s``: only the
        units inside the neighbourhood (``a_k > 0``) are touched. Norms ``|w_k|^2`` are updated in
        closed form; a unit-sum normalisation (supervised maps) only rescales ``c_k``.
        """
        P, N, _ = X.shape
        p = torch.arange(P)
        dt = torch.float64  # the recurrences are exact in real arithmetic; float64 keeps them so
        W0 = self.weight
        # pattern-major layouts, so that the column of pattern s is one contiguous row
        G = torch.bmm(X, X.transpose(1, 2)).to(dt)  # (P, N, N)
        Q = torch.bmm(X, W0.transpose(1, 2)).to(dt)  # (P, N, U)   Q[n, k] = W0_k . x_n (+ sum_m R_km G_mn)
        R = torch.zeros(P, N, self.units, dtype=dt)  # R[n, k] = R_kn
        nrm = (W0 * W0).sum(-1).to(dt)  # (P, U)
        c = torch.ones(P, self.units, dtype=dt)
        rowsum = W0.sum(-1).to(dt)
        xsum = X.sum(-1).to(dt)  # (P, N)
        grid = self.grid.to(dt)
        normalise = isinstance(self.rule, SupervisedKohonen) and self.rule.normalise
        winners = torch.empty_like(order)
        t0 = int(self.steps)
        for t in it:
            s = order[:, t]
            Gs = G[p, s]  # (P, N)
            Ds = c * Q[p, s]  # (P, U)  w_k . x_s
            win = (nrm - 2 * Ds).argmin(-1) if labels is None else labels[p, s]
            winners[:, t] = win
            eta, sigma = self.rule.schedule(t0 + t)
            a = float(eta) * self.rule.neighbourhood(grid, win, sigma.to(dt))  # (P, U)
            b = 1 - a
            nrm = b * b * nrm + 2 * a * b * Ds + a * a * Gs[p, s].unsqueeze(-1)
            c = b * c
            on = (a > 0).any(0).nonzero()  # units inside any participant's neighbourhood
            lo, hi = int(on[0]), int(on[-1]) + 1  # a contiguous span of units: updated in place as a view
            u = a[:, lo:hi] / c[:, lo:hi]  # (P, k), zero outside the neighbourhoods
            Q[:, :, lo:hi].baddbmm_(Gs.unsqueeze(-1), u.unsqueeze(1))
            R[p, s, lo:hi] += u
            if normalise:
                rowsum = b * rowsum + a * xsum[p, s].unsqueeze(-1)
                k = 1.0 / rowsum.clamp_min(1e-300)
                nrm = nrm * k * k
                c = c * k
                rowsum = torch.ones_like(rowsum)
            small = c < 1e-12  # fold tiny scales back in before they cost precision
            if bool(small.any()):
                pi, ki = small.nonzero(as_tuple=True)
                Q[pi, :, ki] *= c[pi, ki].unsqueeze(-1)
                R[pi, :, ki] *= c[pi, ki].unsqueeze(-1)
                c_fold = torch.ones_like(c)
                c_fold[pi, ki] = c[pi, ki]
                W0 = W0 * c_fold.unsqueeze(-1).to(W0.dtype)
                c[pi, ki] = 1.0
        # w_k = c_k W0_k + sum_n (c_k R_kn) x_n, formed once (the scaled coefficients are O(1))
        cR = (R * c.unsqueeze(1)).to(X.dtype)  # (P, N, U)
        self.weight.copy_(c.unsqueeze(-1).to(W0.dtype) * W0 + torch.bmm(cR.transpose(1, 2), X))
        self.steps += order.shape[1]
        return winners

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
        xb, _ = as_batched(x, hi - lo, "pattern")
        w = self.som.weight[..., lo:hi]
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


@torch.no_grad()
def fit_windowed(som, patterns: torch.Tensor, order: torch.Tensor, parts: Sequence[int] | None = None) -> torch.Tensor:
    """Online Kohonen training (eq. 4.5) of every participant of ``som``, touching only each
    participant's own neighbourhood window.

    The arithmetic is that of ``SOM.fit(method='factored')``: each prototype is kept as
    ``w_k = c_k (f_k W0_k + sum_n R_kn x_n)`` and its dot products with the patterns are updated
    in closed form. The difference is *which* units are visited: the rule's truncated Gaussian
    (``theta < rule.cutoff`` -> 0) is non-zero only inside a square of half-width
    ``sigma sqrt(2 ln(1 / cutoff))`` around the winner, so each step gathers that square per
    participant (a unit outside it would get ``a_k = 0``, which leaves every quantity unchanged).
    A step costs ``P x window x K``; batching participants does not widen the touched region to
    the union of their neighbourhoods. ``f_k`` carries the scale folded out of ``c_k`` (so ``W0``
    is never copied).

    ``K`` is the number of distinct pattern *pieces*: ``parts`` (widths summing to the input size)
    cuts every pattern into segments, and a pattern is the concatenation of one piece per segment
    from a small set (Experiment 2's M1_1 sees ``[SS code, PMC_1 code]``: 14 + 7 pieces make its 98
    patterns; PFC_2 sees 14 x 14 image pairs). The dot products are kept per distinct piece,
    ``V_jk = w_k . piece_j / c_k``, and ``w_k . x_n`` is the sum of its pieces' entries, so a step
    costs 21 or 28 numbers per unit instead of 98 or 196. Without ``parts`` the pieces are the
    distinct patterns. The winners decide everything else (``c``, ``f``, ``R`` and the final
    weights are formed exactly as the online rule's closed form), so equal winners mean equal
    weights.

    ``patterns`` ``(N, in)`` or ``(P, N, in)``, ``order`` ``(P, T)``. Returns the winners ``(P, T)``;
    the tests compare them, and the weights, with ``SOM.fit(method='online')``.
    """
    return fit_windowed_many([(som, patterns, order, parts)])[0]


@torch.no_grad()
def fit_windowed_many(jobs) -> list[torch.Tensor]:
    """:func:`fit_windowed` for several maps at once: ``jobs`` is a list of
    ``(som, patterns, order, parts)``. Maps of the same grid, schedule and length train in one
    loop, their participants stacked: the work per step is the same, the fixed cost of a step is
    paid once. Every participant's arithmetic is its own (elementwise, or its own rows of a
    gather), so each map gets the winners and weights it would get alone. Returns the winners."""
    soms = [j[0] for j in jobs]
    s0 = soms[0]
    sched = lambda m: (m.shape, m.rule.eta0, m.rule.eta1, m.rule.sigma0, m.rule.sigma1, m.rule.iterations,  # noqa: E731
                       m.rule.cutoff, int(m.steps), type(m.rule))
    for m in soms:
        if m.supervised or len(m.shape) != 2:
            raise ValueError("som_fit_windowed trains unsupervised 2-D maps")
        if max(m.rule.eta0, m.rule.eta1) >= 1:
            raise ValueError("som_fit_windowed needs learning rates below 1")
    orders = [torch.as_tensor(j[2], dtype=torch.long) for j in jobs]
    if any(sched(m) != sched(s0) for m in soms) or len({o.shape[1] for o in orders}) > 1:
        return [fit_windowed(*j) for j in jobs]
    rule = s0.rule
    U = s0.units
    rows, cols = s0.shape
    dt = torch.float64
    # per job: patterns (P_j, N_j, in_j) in float64 and the weights' precision, distinct pieces
    Xs, X32s, piece_ofs, pieces_all, Ks = [], [], [], [], []
    for (som, patterns, _, parts) in jobs:
        P_j = som.participants
        X = patterns.to(dt)
        X = X.unsqueeze(0).expand(P_j, -1, -1) if X.dim() == 2 else X
        n_in = X.shape[2]
        widths = [n_in] if parts is None else [int(w) for w in parts]
        if sum(widths) != n_in or min(widths) < 1:
            raise ValueError(f"parts must be positive widths summing to the input size {n_in}, got {parts}")
        X32 = X.to(som.weight.dtype)
        bounds = np.cumsum([0] + widths)
        pcs, po_all, K = [], [], 0
        for p in range(P_j):
            pp, po, k0 = [], [], 0
            for b in range(len(widths)):
                seg = slice(int(bounds[b]), int(bounds[b + 1]))
                u, inv = torch.unique(X32[p, :, seg], dim=0, return_inverse=True)
                pp.append((seg, u))
                po.append(inv + k0)
                k0 += u.shape[0]
            pcs.append(pp)
            po_all.append(torch.stack(po, -1))
            K = max(K, k0)
        Xs.append(X)
        X32s.append(X32)
        pieces_all.append(pcs)
        piece_ofs.append(torch.stack(po_all))
        Ks.append(K)
    P = sum(m.participants for m in soms)
    N = max(X.shape[1] for X in Xs)
    K = max(Ks)
    S = max(po.shape[-1] for po in piece_ofs)
    pi = torch.arange(P)
    # V[p, j, k] = w_k . piece_j / c_k (piece-major; one padding unit, index U, absorbs the window
    # cells that fall off the map); G[p, n, j] = x_n . piece_j on piece j's segment; gdiag = |x_n|^2
    V = torch.zeros(P, K, U + 1, dtype=dt)
    G = torch.zeros(P, N, K, dtype=dt)
    nrm = torch.zeros(P, U + 1, dtype=dt)
    gdiag = torch.zeros(P, N, dtype=dt)
    piece_of = torch.zeros(P, N, S, dtype=torch.long)
    order = torch.cat(orders)
    i = 0
    for som, X, pcs, po in zip(soms, Xs, pieces_all, piece_ofs):
        W0 = som.weight
        for p in range(som.participants):  # one participant at a time, in the weights' precision (as the online rule)
            k0 = 0
            for seg, u in pcs[p]:
                kb = u.shape[0]
                V[i, k0:k0 + kb, :U] = (u @ W0[p, :, seg].T).to(dt)
                G[i, : X.shape[1], k0:k0 + kb] = X[p, :, seg] @ u.to(dt).T
                k0 += kb
            nrm[i, :U] = squared_norms(W0[p]).to(dt)
            gdiag[i, : X.shape[1]] = (X[p] @ X[p].T).diagonal()
            piece_of[i, : X.shape[1], : po.shape[-1]] = po[p]
            i += 1
    if any(po.shape[-1] < S for po in piece_ofs):  # a job with fewer segments reads a piece column that stays zero
        V = torch.cat([V, torch.zeros(P, 1, U + 1, dtype=dt)], 1)
        G = torch.cat([G, torch.zeros(P, N, 1, dtype=dt)], 2)
        for j, po in enumerate(piece_ofs):
            if po.shape[-1] < S:
                first = sum(m.participants for m in soms[:j])
                piece_of[first:first + po.shape[0], :, po.shape[-1]:] = K
        K += 1
    c = torch.ones(P, U + 1, dtype=dt)
    f = torch.ones(P, U + 1, dtype=dt)
    R = torch.zeros(P, U + 1, N, dtype=dt)
    reach = float(np.sqrt(2.0 * np.log(1.0 / rule.cutoff))) if rule.cutoff > 0 else float("inf")
    o = torch.arange(-(rows - 1), rows).unsqueeze(1), torch.arange(-(cols - 1), cols).unsqueeze(0)
    offs = torch.stack(torch.broadcast_tensors(*o), -1).reshape(-1, 2)  # every grid offset
    d2_offs = (offs**2).sum(-1).double()
    offs, d2_offs = offs[d2_offs.argsort(stable=True)], d2_offs.sort(stable=True).values  # nearest first
    R_f, nrm_f, c_f, V_rows, V_f = R.view(-1), nrm.view(-1), c.view(-1), V.view(P * K, U + 1), V.view(-1)
    # rows of V_rows holding each step's pattern pieces: (T, P, segments)
    piece_rows = (pi.view(P, 1, 1) * K + piece_of[pi.unsqueeze(1), order]).transpose(0, 1).contiguous()
    vbase = (pi.view(P, 1, 1) * K + torch.arange(K).view(1, K, 1)) * (U + 1)  # (P, K, 1) offsets of V's rows
    base = (pi * (U + 1)).unsqueeze(1)
    winners = torch.empty_like(order)
    t0 = int(s0.steps)
    for t in range(order.shape[1]):
        s = order[:, t]
        rows_s = piece_rows[t]  # (P, segments)
        Ds = V_rows.index_select(0, rows_s[:, 0])
        for b in range(1, S):
            Ds += V_rows.index_select(0, rows_s[:, b])
        Ds *= c  # (P, U + 1): w_k . x_s
        win = (nrm[:, :U] - 2 * Ds[:, :U]).argmin(-1)
        winners[:, t] = win
        eta, sigma = rule.schedule(t0 + t)
        # grid offsets whose theta can reach the cutoff: d^2 <= 2 sigma^2 ln(1 / cutoff) (+1 for rounding)
        lim = min(float(sigma) ** 2 * reach**2 + 1.0, float(rows**2 + cols**2))
        n = int(torch.searchsorted(d2_offs, torch.tensor(lim, dtype=torch.float64), right=True))
        dr, dq, d2 = offs[:n, 0], offs[:n, 1], d2_offs[:n].float()
        theta = torch.exp(-d2 / (2.0 * sigma**2))  # the rule's neighbourhood, same float32 arithmetic
        theta = torch.where(theta < rule.cutoff, torch.zeros_like(theta), theta)
        r = (win // cols).unsqueeze(1) + dr  # (P, k)
        q = (win % cols).unsqueeze(1) + dq
        inside = (r >= 0) & (r < rows) & (q >= 0) & (q < cols)
        idx = torch.where(inside, r * cols + q, torch.full_like(r, U))
        a = (eta * theta).to(dt) * inside  # (P, k), zero on the padding unit
        b_ = 1 - a
        flat = (idx + base).reshape(-1)  # rows of the flattened (P (U + 1), ...) buffers
        nrm_w, Ds_w, c_w = nrm_f[flat].view(P, -1), Ds.reshape(-1)[flat].view(P, -1), c_f[flat].view(P, -1)
        nrm_f.index_copy_(0, flat, (b_ * b_ * nrm_w + 2 * a * b_ * Ds_w + a * a * gdiag[pi, s].unsqueeze(-1)).reshape(-1))
        c_w = b_ * c_w
        c_f.index_copy_(0, flat, c_w.reshape(-1))
        u = a / c_w  # zero outside the neighbourhood and on the padding unit
        Gs = G[pi, s]  # (P, K)
        if idx.shape[1] * 16 > U:  # a wide neighbourhood: one contiguous pass over every unit is cheaper
            V.addcmul_(Gs.unsqueeze(-1), torch.zeros(P, 1, U + 1, dtype=dt).scatter_(2, idx.unsqueeze(1), u.unsqueeze(1)))
        else:
            V_f.index_add_(0, (vbase + idx.unsqueeze(1)).view(-1), (Gs.unsqueeze(-1) * u.unsqueeze(1)).view(-1))
        R_f.index_add_(0, flat * N + s.repeat_interleave(idx.shape[1]), u.reshape(-1))
        small = c_w < 1e-12  # fold tiny scales back in before they cost precision
        if bool(small.any()):
            pp_, kk = small.nonzero(as_tuple=True)
            uu = idx[pp_, kk]
            ok = uu < U
            pp_, uu = pp_[ok], uu[ok]
            cc = c[pp_, uu].unsqueeze(-1)
            V[pp_, :, uu] *= cc
            R[pp_, uu] *= cc
            f[pp_, uu] *= cc.squeeze(-1)
            c[pp_, uu] = 1.0
    out, i = [], 0
    for (som, patterns, _, _), X32 in zip(jobs, X32s):
        W0, Nj = som.weight, X32.shape[1]
        scales, coefs = [], []
        for p in range(som.participants):  # w_k = c_k f_k W0_k + (c_k R_k) X: coefficients in float64, product in the weights' precision
            coefs.append((c[i, :U, None] * R[i, :U, :Nj]).to(W0.dtype))
            scales.append((c[i, :U] * f[i, :U]).to(W0.dtype))
            form_windowed_weights(W0[p], scales[-1], coefs[-1], X32[p])
            i += 1
        som.steps += order.shape[1]
        # what the final weights were formed from (see ``windowed_factors``); not part of the state
        som.windowed_factors = {"scale": torch.stack(scales), "coef": torch.stack(coefs),
                                "patterns": X32[0].clone() if patterns.dim() == 2 else X32.clone()}
        out.append(winners[i - som.participants:i])
    return out


WINDOWED_BLOCK = 512  # units per block of the final product (each row of a product is its own)


@torch.no_grad()
def form_windowed_weights(w0: torch.Tensor, scale: torch.Tensor, coef: torch.Tensor, patterns: torch.Tensor) -> None:
    """The last step of :func:`fit_windowed_many`, in place on one participant's initial weights
    ``w0`` ``(U, in)``: ``w_k = scale_k w0_k + sum_n coef_kn x_n``, the product a block of
    ``WINDOWED_BLOCK`` units at a time, in the weights' precision (``scale`` ``(U,)``, ``coef``
    ``(U, N)``, ``patterns`` ``(N, in)``, all of the weights' dtype)."""
    w0.mul_(scale.unsqueeze(-1))
    for lo in range(0, w0.shape[0], WINDOWED_BLOCK):
        w0[lo:lo + WINDOWED_BLOCK].add_(coef[lo:lo + WINDOWED_BLOCK] @ patterns)


@torch.no_grad()
def windowed_factors(som) -> dict:
    """The factors :func:`fit_windowed_many` formed ``som``'s current weights from: ``scale``
    ``(P, U)``, ``coef`` ``(P, U, N)`` and ``patterns`` ``(N, in)`` (shared) or ``(P, N, in)``.
    Together with the initial weights they give the trained weights back (:func:`rebuild_windowed`;
    bit for bit on the same CPU and thread count), at ``N / in`` of their size. Raises if the map
    was not trained by the windowed form in this process."""
    f = getattr(som, "windowed_factors", None)
    if f is None:
        raise ValueError(f"SOM {som.name!r} was not trained by fit_windowed in this process: no factors to save")
    return f


@torch.no_grad()
def rebuild_windowed(som, factors: dict) -> None:
    """Form ``som``'s trained weights from its *initial* weights (in place) and ``factors`` of
    :func:`windowed_factors`, by the very products of the trainer (identical on the same CPU and threads)."""
    scale, coef, X = factors["scale"], factors["coef"], factors["patterns"]
    P, U = som.participants, som.units
    if scale.shape != (P, U) or coef.shape[:2] != (P, U) or X.shape[-1] != som.n_in or X.shape[-2] != coef.shape[2]:
        raise ValueError(f"SOM {som.name!r}: factors of shapes scale {tuple(scale.shape)}, coef {tuple(coef.shape)}, "
                         f"patterns {tuple(X.shape)} do not fit {P} participants x {U} units x {som.n_in} inputs")
    for p in range(P):
        form_windowed_weights(som.weight[p], scale[p].to(som.weight.dtype), coef[p].to(som.weight.dtype),
                              (X if X.dim() == 2 else X[p]).to(som.weight.dtype))
