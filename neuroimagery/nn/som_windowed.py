"""The per-participant windowed form of online Kohonen training (``SOM.fit(method='windowed')``),
registered for a SOM (:class:`Windowed`), and the factors it forms the trained weights from
(``som.learnt_factors``, saved in checkpoints instead of the weights): how it records them,
rebuilds the weights from them and bounds the rounding of that rebuild.

A CPU trainer: it keeps its bookkeeping in float64 host tensors and NumPy, and refuses maps whose
weights live on another device.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from .forms import Form, register
from .functional import squared_norms
from .numerics import rounding_bound
from .rules import Kohonen
from .som import SOM
from .som_factored import refuse


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


def _schedule_key(m) -> tuple:
    """What maps must share to train in one loop: grid, schedule, cutoff, steps so far, rule."""
    r = m.rule
    return (m.shape, r.eta0, r.eta1, r.sigma0, r.sigma1, r.iterations, r.cutoff, int(m.steps), type(r))


def _check_trainable(soms) -> None:
    """Refuse a map the windowed trainer cannot train (supervised, not 2-D, a rate of 1, off the CPU)."""
    for m in soms:
        if m.supervised or len(m.shape) != 2:
            raise ValueError("som_fit_windowed trains unsupervised 2-D maps")
        if max(m.rule.eta0, m.rule.eta1) >= 1:
            raise ValueError("som_fit_windowed needs learning rates below 1")
        if m.weight.device.type != "cpu":
            raise ValueError(f"som_fit_windowed trains on the CPU; SOM {m.name!r} has its weights on {m.weight.device}")


@torch.no_grad()
def fit_windowed_many(jobs) -> list[torch.Tensor]:
    """:func:`fit_windowed` for several maps at once: ``jobs`` is a list of
    ``(som, patterns, order, parts)``. Maps of the same grid, schedule and length train in one
    loop, their participants stacked: the work per step is the same, the fixed cost of a step is
    paid once. Every participant's arithmetic is its own (elementwise, or its own rows of a
    gather), so each map gets the winners and weights it would get alone. Returns the winners."""
    soms = [j[0] for j in jobs]
    s0 = soms[0]
    _check_trainable(soms)
    orders = [torch.as_tensor(j[2], dtype=torch.long) for j in jobs]
    if any(_schedule_key(m) != _schedule_key(s0) for m in soms) or len({o.shape[1] for o in orders}) > 1:
        return [fit_windowed(*j) for j in jobs]
    rows, cols = s0.shape
    pieces = [_Pieces(som, patterns, parts) for (som, patterns, _, parts) in jobs]
    V, G, nrm, gdiag, piece_of = _dot_tables(soms, pieces)
    P, U1 = nrm.shape
    c = torch.ones(P, U1, dtype=V.dtype)
    f = torch.ones(P, U1, dtype=V.dtype)
    R = torch.zeros(P, U1, G.shape[1], dtype=V.dtype)
    offs, d2_offs = _grid_offsets(rows, cols)
    order = torch.cat(orders)
    winners = torch.empty_like(order)
    from . import som_windowed_kernel as kernel

    steps = kernel.run if kernel.available() else _steps_torch
    steps(s0.rule, int(s0.steps), V, nrm, c, f, R, G, gdiag, piece_of, order, winners, offs, d2_offs, rows, cols)
    return _form_weights(jobs, pieces, c, f, R, order.shape[1], winners)


class _Pieces:
    """One job's patterns ``(P_j, N_j, in_j)`` in float64 (``X``) and in the weights' precision
    (``X32``), each participant's distinct pieces per segment (``pieces[p]``: ``(segment slice,
    distinct rows)``), the piece of each pattern per segment (``piece_of`` ``(P_j, N_j, segments)``,
    numbered across segments) and the largest number of pieces of a participant (``K``)."""

    def __init__(self, som, patterns: torch.Tensor, parts):
        P_j = som.participants
        X = patterns.to(torch.float64)
        X = X.unsqueeze(0).expand(P_j, -1, -1) if X.dim() == 2 else X
        n_in = X.shape[2]
        widths = [n_in] if parts is None else [int(w) for w in parts]
        if sum(widths) != n_in or min(widths) < 1:
            raise ValueError(f"parts must be positive widths summing to the input size {n_in}, got {parts}")
        X32 = X.to(som.weight.dtype)
        bounds = np.cumsum([0] + widths)
        self.X, self.X32, self.pieces, self.K = X, X32, [], 0
        of_all = []
        for p in range(P_j):
            pp, po, k0 = [], [], 0
            for b in range(len(widths)):
                seg = slice(int(bounds[b]), int(bounds[b + 1]))
                u, inv = torch.unique(X32[p, :, seg], dim=0, return_inverse=True)
                pp.append((seg, u))
                po.append(inv + k0)
                k0 += u.shape[0]
            self.pieces.append(pp)
            of_all.append(torch.stack(po, -1))
            self.K = max(self.K, k0)
        self.piece_of = torch.stack(of_all)


def _dot_tables(soms, pieces: list[_Pieces]):
    """The step loop's float64 tables over all participants stacked: ``V[p, j, k] = w_k . piece_j
    / c_k`` (piece-major; one padding unit, index U, absorbs the window cells that fall off the
    map), ``G[p, n, j] = x_n . piece_j`` on piece j's segment, the norms ``|w_k|^2``, ``gdiag =
    |x_n|^2`` and ``piece_of`` ``(P, N, segments)``. Returns ``V, G, nrm, gdiag, piece_of``."""
    dt = torch.float64
    U = soms[0].units
    P = sum(m.participants for m in soms)
    N = max(pc.X.shape[1] for pc in pieces)
    K = max(pc.K for pc in pieces)
    S = max(pc.piece_of.shape[-1] for pc in pieces)
    V = torch.zeros(P, K, U + 1, dtype=dt)
    G = torch.zeros(P, N, K, dtype=dt)
    nrm = torch.zeros(P, U + 1, dtype=dt)
    gdiag = torch.zeros(P, N, dtype=dt)
    piece_of = torch.zeros(P, N, S, dtype=torch.long)
    i = 0
    for som, pc in zip(soms, pieces):
        W0, X, n = som.weight, pc.X, pc.X.shape[1]
        for p in range(som.participants):  # one participant at a time, in the weights' precision (as the online rule)
            k0 = 0
            for seg, u in pc.pieces[p]:
                kb = u.shape[0]
                V[i, k0:k0 + kb, :U] = (u @ W0[p, :, seg].T).to(dt)
                G[i, :n, k0:k0 + kb] = X[p, :, seg] @ u.to(dt).T
                k0 += kb
            nrm[i, :U] = squared_norms(W0[p]).to(dt)
            gdiag[i, :n] = (X[p] @ X[p].T).diagonal()
            piece_of[i, :n, : pc.piece_of.shape[-1]] = pc.piece_of[p]
            i += 1
    if any(pc.piece_of.shape[-1] < S for pc in pieces):  # a job with fewer segments reads a piece column that stays zero
        V = torch.cat([V, torch.zeros(P, 1, U + 1, dtype=dt)], 1)
        G = torch.cat([G, torch.zeros(P, N, 1, dtype=dt)], 2)
        first = 0
        for som, pc in zip(soms, pieces):
            if pc.piece_of.shape[-1] < S:
                piece_of[first:first + pc.piece_of.shape[0], :, pc.piece_of.shape[-1]:] = K
            first += som.participants
    return V, G, nrm, gdiag, piece_of


def _grid_offsets(rows: int, cols: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Every grid offset ``(dr, dq)`` of a ``rows x cols`` map and its squared length (float64),
    nearest first (a stable sort)."""
    o = torch.arange(-(rows - 1), rows).unsqueeze(1), torch.arange(-(cols - 1), cols).unsqueeze(0)
    offs = torch.stack(torch.broadcast_tensors(*o), -1).reshape(-1, 2)
    d2_offs = (offs**2).sum(-1).double()
    return offs[d2_offs.argsort(stable=True)], d2_offs.sort(stable=True).values


def _form_weights(jobs, pieces: list[_Pieces], c, f, R, T: int, winners) -> list[torch.Tensor]:
    """Each map's trained weights from the loop's ``c``, ``f``, ``R``, in place; its factors in
    ``som.learnt_factors``; its steps advanced by ``T``. Returns each map's winners."""
    out, i = [], 0
    for (som, patterns, _, _), pc in zip(jobs, pieces):
        W0, X32 = som.weight, pc.X32
        U, Nj = som.units, X32.shape[1]
        scales, coefs = [], []
        for p in range(som.participants):  # w_k = c_k f_k W0_k + (c_k R_k) X: coefficients in float64, product in the weights' precision
            coefs.append((c[i, :U, None] * R[i, :U, :Nj]).to(W0.dtype))
            scales.append((c[i, :U] * f[i, :U]).to(W0.dtype))
            form_windowed_weights(W0[p], scales[-1], coefs[-1], X32[p])
            i += 1
        som.steps += T
        # what the final weights were formed from (:class:`Windowed`); not part of the state
        som.learnt_factors = {"kind": Windowed.kind, "scale": torch.stack(scales), "coef": torch.stack(coefs),
                              "patterns": X32[0].clone() if patterns.dim() == 2 else X32.clone()}
        out.append(winners[i - som.participants:i])
    return out


@torch.no_grad()
def _steps_torch(rule, t0, V, nrm, c, f, R, G, gdiag, piece_of, order, winners, offs, d2_offs, rows, cols) -> None:
    """The steps of :func:`fit_windowed_many` as tensor operations, in place on ``V``, ``nrm``,
    ``c``, ``f``, ``R`` and ``winners`` (the compiled loop of :mod:`.som_windowed_kernel` does the
    same arithmetic)."""
    P, K, U1 = V.shape
    U, N, S, dt = U1 - 1, R.shape[2], piece_of.shape[2], V.dtype
    pi = torch.arange(P)
    reach = float(np.sqrt(2.0 * np.log(1.0 / rule.cutoff))) if rule.cutoff > 0 else float("inf")
    R_f, nrm_f, c_f, V_rows, V_f = R.view(-1), nrm.view(-1), c.view(-1), V.view(P * K, U + 1), V.view(-1)
    # rows of V_rows holding each step's pattern pieces: (T, P, segments)
    piece_rows = (pi.view(P, 1, 1) * K + piece_of[pi.unsqueeze(1), order]).transpose(0, 1).contiguous()
    vbase = (pi.view(P, 1, 1) * K + torch.arange(K).view(1, K, 1)) * (U + 1)  # (P, K, 1) offsets of V's rows
    base = (pi * (U + 1)).unsqueeze(1)
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
def rebuild_windowed(som, factors: dict) -> None:
    """Form ``som``'s trained weights from its *initial* weights (in place) and the ``factors``
    :func:`fit_windowed_many` left in ``som.learnt_factors`` (``scale`` ``(P, U)``, ``coef``
    ``(P, U, N)``, ``patterns`` ``(N, in)`` shared or ``(P, N, in)``), by the very products of the
    trainer (identical on the same CPU and threads)."""
    scale, coef, X = factors["scale"], factors["coef"], factors["patterns"]
    P, U = som.participants, som.units
    if scale.shape != (P, U) or coef.shape[:2] != (P, U) or X.shape[-1] != som.n_in or X.shape[-2] != coef.shape[2]:
        raise ValueError(f"SOM {som.name!r}: factors of shapes scale {tuple(scale.shape)}, coef {tuple(coef.shape)}, "
                         f"patterns {tuple(X.shape)} do not fit {P} participants x {U} units x {som.n_in} inputs")
    for p in range(P):
        form_windowed_weights(som.weight[p], scale[p].to(som.weight.dtype), coef[p].to(som.weight.dtype),
                              (X if X.dim() == 2 else X[p]).to(som.weight.dtype))


def _shared(X):
    """One pattern set for all participants (an expanded view): the windowed factors keep one copy."""
    return X[0] if X.dim() == 3 and X.shape[0] > 0 and X.stride(0) == 0 else X


@register(Kohonen, SOM)
class Windowed(Form):
    """``method='windowed'`` (never chosen by 'auto'): :func:`fit_windowed`, several maps of one
    schedule in one loop (:func:`fit_windowed_many`); its factors are the scale factors and
    coefficients over the pattern set, ``w = scale w0 + coef X``."""

    name, kind, options, auto = "windowed", "som_windowed", ("parts",), False

    def why_not(self, som, rule, call):
        if call.labels is not None:
            return "trains unsupervised maps; use 'factored' with labels"
        return refuse(som)

    def run(self, som, rule, call) -> torch.Tensor:
        return fit_windowed(som, _shared(call.X), call.order, call.options.get("parts"))

    @staticmethod
    def run_many(jobs) -> list[torch.Tensor]:
        return fit_windowed_many([(som, _shared(X), order, parts) for som, X, order, labels, parts in jobs])

    def rebuild(self, som, factors: dict) -> None:
        rebuild_windowed(som, factors)

    @torch.no_grad()
    def bound(self, f: dict, w0, saved, rows):
        """``w = scale w0 + sum_n coef_n x_n`` in float32: ``N + 1`` terms."""
        d = torch.float64
        X = f["patterns"].to(d).abs()
        coef = f["coef"][:, rows].to(d).abs()
        prod = torch.einsum("pkn,ni->pki" if X.dim() == 2 else "pkn,pni->pki", coef, X)
        return rounding_bound(f["scale"][:, rows].to(d).abs().unsqueeze(-1) * w0.to(d).abs() + prod, coef.shape[-1] + 1)
