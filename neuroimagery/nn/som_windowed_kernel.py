"""The step loop of :func:`~neuroimagery.nn.som_windowed.fit_windowed_many` compiled (numba), for
CPUs: the same float64 operations, element for element and in the same order, as the torch loop
of that module, so the two give the same bits (``tests/test_som.py`` compares them); a step costs
its arithmetic instead of some thirty tensor operations' dispatch.

The rule's neighbourhood ``eta(t) theta`` of each step stays a torch computation (:func:`rates`):
its ``exp`` is torch's, and every participant and unit reads it from there. What the loop does per
participant ``p`` and step ``t`` (pattern ``s``): the winner ``argmin_k |w_k|^2 - 2 w_k . x_s``
with ``w_k . x_s = c_k sum_b V[p, piece_b(s), k]``; then, for each unit ``k`` of the window inside
the map with rate ``a``: ``|w_k|^2 <- (1 - a)^2 |w_k|^2 + 2 a (1 - a) w_k . x_s + a^2 |x_s|^2``,
``c_k <- (1 - a) c_k``, ``u = a / c_k``, ``V[p, j, k] += G[p, s, j] u`` for every piece ``j``,
``R[p, k, s] += u``, and a scale ``c_k < 1e-12`` folded back into ``V``, ``R`` and ``f``.
"""
from __future__ import annotations

import numpy as np
import torch

from . import compiled

CHUNK = 256  # steps whose rates are formed (in torch) before the compiled loop runs them


def available() -> bool:
    """Whether the compiled loop can run (numba is installed)."""
    return compiled.installed()


def rates(rule, t0: int, T: int, d2_offs: torch.Tensor, rows: int, cols: int):
    """The neighbourhood rates of steps ``t0 .. t0 + T - 1``, as the torch loop forms them: per step
    the number ``n`` of grid offsets (nearest first) that can reach the cutoff and
    ``(eta theta)`` of those offsets in float32, widened to float64. Returns ``(n (T,), a (T, n_max))``."""
    reach = float(np.sqrt(2.0 * np.log(1.0 / rule.cutoff))) if rule.cutoff > 0 else float("inf")
    ns, rows_a = [], []
    for t in range(T):
        eta, sigma = rule.schedule(t0 + t)
        lim = min(float(sigma) ** 2 * reach**2 + 1.0, float(rows**2 + cols**2))
        n = int(torch.searchsorted(d2_offs, torch.tensor(lim, dtype=torch.float64), right=True))
        d2 = d2_offs[:n].float()
        theta = torch.exp(-d2 / (2.0 * sigma**2))  # the rule's neighbourhood, same float32 arithmetic
        theta = torch.where(theta < rule.cutoff, torch.zeros_like(theta), theta)
        ns.append(n)
        rows_a.append((eta * theta).to(torch.float64))
    a = torch.zeros(T, max(ns), dtype=torch.float64)
    for t, r in enumerate(rows_a):
        a[t, : r.shape[0]] = r
    return np.asarray(ns, dtype=np.int64), a.numpy()


def _loop(V, nrm, c, f, R, G, gdiag, piece_of, order, winners, ns, a, dr, dq, rows, cols, t_lo):  # pragma: no cover
    """Steps ``t_lo .. t_lo + len(ns) - 1`` of every participant, in place (see the module docstring).
    Each number gets the torch loop's operations in its order; only the order in which different
    numbers are visited differs (one piece row of ``V`` at a time, for the cache)."""
    P, K, U1 = V.shape
    U = U1 - 1
    S = piece_of.shape[2]
    Ds = np.empty(U, dtype=np.float64)
    e = np.empty(U, dtype=np.float64)
    n_max = a.shape[1]
    cell = np.empty(n_max, dtype=np.int64)
    ucell = np.empty(n_max, dtype=np.float64)
    for p in range(P):
        for tt in range(ns.shape[0]):
            t = t_lo + tt
            s = order[p, t]
            Ds[:] = V[p, piece_of[p, s, 0], :U]
            for b in range(1, S):
                Ds += V[p, piece_of[p, s, b], :U]
            Ds *= c[p, :U]
            for k in range(U):
                e[k] = nrm[p, k] - 2.0 * Ds[k]
            win = np.argmin(e)  # the first smallest, as torch's argmin
            winners[p, t] = win
            wr, wq = win // cols, win % cols
            g = gdiag[p, s]
            m = 0
            for j in range(ns[tt]):
                r, q = wr + dr[j], wq + dq[j]
                if r < 0 or r >= rows or q < 0 or q >= cols:
                    continue
                k = r * cols + q
                aj = a[tt, j]
                bj = 1.0 - aj
                nrm[p, k] = bj * bj * nrm[p, k] + 2.0 * aj * bj * Ds[k] + aj * aj * g
                cw = bj * c[p, k]
                c[p, k] = cw
                cell[m] = k
                ucell[m] = aj / cw
                m += 1
            for jj in range(K):
                gj = G[p, s, jj]
                for i in range(m):
                    V[p, jj, cell[i]] += gj * ucell[i]
            for i in range(m):
                k = cell[i]
                R[p, k, s] += ucell[i]
                cw = c[p, k]
                if cw < 1e-12:  # fold tiny scales back in before they cost precision
                    for jj in range(K):
                        V[p, jj, k] *= cw
                    for n in range(R.shape[2]):
                        R[p, k, n] *= cw
                    f[p, k] *= cw
                    c[p, k] = 1.0


_kernels = compiled.Kernels(globals())


def run(rule, t0: int, V, nrm, c, f, R, G, gdiag, piece_of, order, winners, offs, d2_offs, rows: int, cols: int) -> None:
    """All ``order.shape[1]`` steps of the windowed fit, in place on the torch tensors ``V``,
    ``nrm``, ``c``, ``f``, ``R`` (float64, contiguous) and ``winners``."""
    loop = _kernels("loop")
    arrs = [x.numpy() for x in (V, nrm, c, f, R, G.contiguous(), gdiag.contiguous(), piece_of.contiguous(),
                                order.contiguous(), winners)]
    dr, dq = offs[:, 0].contiguous().numpy(), offs[:, 1].contiguous().numpy()
    T = order.shape[1]
    for lo in range(0, T, CHUNK):
        ns, a = rates(rule, t0 + lo, min(CHUNK, T - lo), d2_offs, rows, cols)
        loop(*arrs, ns, a, dr, dq, rows, cols, lo)
