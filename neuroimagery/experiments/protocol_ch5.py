"""Pieces shared by the chapter-5 mental-rotation experiments (Experiments 1 and 2).

* the stimuli: edge maps (32x32, {0, 1}) of the upside-down L (object A) and its mirror
  (object B), or of a user's folder, through the project's vision pipeline;
* the exact shortcut for outstar Hebbian training shared by every participant
  (:func:`hebbian_shared`);
* the trial table -> summary -> report plumbing common to both experiments.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import pandas as pd
import torch

from ..analysis.summary import TRIAL_COLUMNS, check_trials
from ..nn import AllToAll, Hebbian


# ---------------------------------------------------------------------------------- stimuli
def stimulus_set(cfg):
    """The L set (Exp. 1-2) or the user's folder set when ``cfg.stimuli.kind == 'folder'``."""
    from ..vision.stimulus_sets import get_stimulus_set, resolve_stimulus_set

    if getattr(cfg.stimuli, "kind", "builtin") == "folder":
        return resolve_stimulus_set(cfg.stimuli, "L")
    return get_stimulus_set("L")


def edge_maps(cfg, sset, items: Sequence[tuple[str, float]]) -> torch.Tensor:
    """Binary edge maps ``(N, 32, 32)`` of ``(object, angle)`` items (first appearance)."""
    app = sset.appearances[0]
    full = [(o, float(a), app) for o, a in items]
    try:  # the eye of the vision package (direct or camera path), when it offers one
        from ..vision import make_eye  # type: ignore

        return make_eye(cfg.vision).edge_maps(sset, items=full, size=32).float()
    except ImportError:
        from ..vision.edges import edge_pipeline

        imgs = [sset.image(o, a, ap) for o, a, ap in full]
        return edge_pipeline(imgs, size=32, red_threshold=cfg.vision.red_threshold).float()


def objects_of(sset) -> list[str]:
    """The two objects the chapter-5 models are trained on (A and its mirror B for the L set)."""
    objs = list(sset.objects)
    if len(objs) < 2:
        raise ValueError(f"stimulus set {sset.name!r} needs two objects (a shape and its mirror), has {objs}")
    return objs[:2]


# ----------------------------------------------------------------------- Hebbian, all participants
@torch.no_grad()
def hebbian_shared(weight0: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, eta: float) -> torch.Tensor:
    """Online outstar Hebbian training (eq. 4.2-4.3) of ``P`` participants on one shared sequence.

    The outstar Oja step ``w_ji <- (1 - eta x_i) w_ji + eta x_i y_j`` (``Hebbian(eta, 'outstar')``
    applied one pattern at a time) is affine in the weights with coefficients that depend only on
    the presented activity. After the sequence ``t = 1..T``::

        w_ji = a_i w0_ji + sum_t eta x_i^t y_j^t S_ti,   a_i = prod_t (1 - eta x_i^t),
        S_ti = prod_{s > t} (1 - eta x_i^s)

    so every participant's weights follow from one matrix product, exactly (the test suite checks
    this against ``Connection.learn`` step by step). ``weight0`` ``(P, out, in)``, ``pre``
    ``(T, in)``, ``post`` ``(T, out)``; returns the trained ``(P, out, in)``.
    """
    dt = torch.float64
    keep = 1.0 - eta * pre.to(dt)  # (T, in)
    # suffix products S_t = prod_{s>t} keep_s
    rev = torch.cumprod(torch.flip(keep, [0]), 0)
    suffix = torch.cat([torch.flip(rev, [0])[1:], torch.ones_like(keep[:1])], 0)
    a = rev[-1]  # (in,)
    b = post.to(dt).T @ (eta * pre.to(dt) * suffix)  # (out, in)
    return (weight0.to(dt) * a + b).to(weight0.dtype)


def hebbian_online(weight0: torch.Tensor, pre: torch.Tensor, post: torch.Tensor, eta: float) -> torch.Tensor:
    """Reference: the same training through ``AllToAll.learn`` one pattern at a time (slow)."""
    P, n_out, n_in = weight0.shape
    c = AllToAll(n_in, n_out, participants=P, init="zeros", rules=Hebbian(eta, "outstar"))
    c.weight.copy_(weight0)
    c.train()
    for t in range(pre.shape[0]):
        c.learn(pre[t].expand(P, 1, n_in), post[t].expand(P, 1, n_out))
    return c.weight.clone()


# --------------------------------------------------------------------------------- trials
def image_table(cfg, sset, angles: Sequence[float]) -> dict:
    """Edge maps of every (object, angle) of the L set, keyed ``(object index, angle)``, flattened."""
    objs = objects_of(sset)
    items = [(o, float(a)) for o in objs for a in angles]
    maps = edge_maps(cfg, sset, items).reshape(len(items), -1)
    return {(objs.index(o), a): maps[i] for i, (o, a) in enumerate(items)}


def train_and_save(cfg, run, model_cls, e, angles: Sequence[float]):
    """Train ``model_cls(e, participants, seed)`` on the L set at ``angles`` and checkpoint it."""
    from ..vision.stimulus_sets import get_stimulus_set

    model = model_cls(e, cfg.participants, cfg.seed)
    model.fit(image_table(cfg, get_stimulus_set("L"), angles))
    run.save_checkpoint("model", {"state_dict": model.state_dict(), "participants": cfg.participants})
    return model


def load_model(cfg, checkpoint_dir, model_cls, e):
    """The model of a training run's ``checkpoints/model.pt``, in eval mode."""
    from ..run import load_checkpoint

    state = load_checkpoint(checkpoint_dir, "model")
    model = model_cls(e, state["participants"], cfg.seed)
    model.load_state_dict(state["state_dict"])
    model.eval()
    return model


def trials_frame(rows: list[dict]) -> pd.DataFrame:
    """Rows -> the trials table of RESULTS.md (columns in the public order, extras after)."""
    df = pd.DataFrame(rows)
    for c in TRIAL_COLUMNS:
        if c not in df:
            df[c] = np.nan
    return check_trials(df)


def pearson(x: Sequence[float], y: Sequence[float]) -> float | None:
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    return float(np.corrcoef(x, y)[0, 1])


def to_np(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().float().numpy()


@torch.no_grad()
def hebbian_indexed(weight0: torch.Tensor, pre: torch.Tensor, post_index: torch.Tensor, post_set: torch.Tensor,
                    eta: float) -> torch.Tensor:
    """Online outstar Hebbian training with a different sequence per participant, in closed form.

    Same algebra as :func:`hebbian_shared`; the outputs come from a finite set ``post_set``
    ``(K, out)`` indexed by ``post_index`` ``(P, T)``, so the sum over time is first gathered per
    output pattern (``(P, K, in)``) and then expanded with one small product. ``pre`` ``(P, T, in)``.
    """
    keep = 1.0 - eta * pre.float()
    rev = torch.cumprod(torch.flip(keep, [1]), 1)
    suffix = torch.cat([torch.flip(rev, [1])[:, 1:], torch.ones_like(keep[:, :1])], 1)
    a = rev[:, -1]  # (P, in)
    c = eta * pre.float() * suffix  # (P, T, in)
    P, T, n_in = pre.shape
    C = torch.zeros(P, post_set.shape[0], n_in)
    C.scatter_add_(1, post_index.long().unsqueeze(-1).expand(P, T, n_in), c)
    b = torch.einsum("ko,pki->poi", post_set.float(), C)
    return weight0 * a.unsqueeze(1) + b


# ------------------------------------------------------------------ SOM, all participants at once
@torch.no_grad()
def som_fit_windowed(som, patterns: torch.Tensor, order: torch.Tensor) -> torch.Tensor:
    """Online Kohonen training (eq. 4.5) of every participant of ``som``, touching only each
    participant's own neighbourhood window.

    The arithmetic is that of ``SOM.fit(method='factored')``: each prototype is kept as
    ``w_k = c_k (f_k W0_k + sum_n R_kn x_n)`` and its dot products with the ``N`` patterns
    ``Q_kn = w_k . x_n / c_k`` are updated in closed form. The difference is *which* units are
    visited: the rule's truncated Gaussian (``theta < rule.cutoff`` -> 0) is non-zero only inside
    a square of half-width ``sigma sqrt(2 ln(1 / cutoff))`` around the winner, so each step
    gathers that square per participant (a unit outside it would get ``a_k = 0``, which leaves
    every quantity unchanged). A step costs ``P x window x N``; batching participants no longer
    widens the touched region to the union of their neighbourhoods. ``f_k`` carries the scale
    folded out of ``c_k`` (so ``W0`` is never copied). ``patterns`` ``(N, in)`` or ``(P, N, in)``,
    ``order`` ``(P, T)``. Returns the winners ``(P, T)``; the tests compare them, and the
    weights, with ``SOM.fit(method='online')``.
    """
    rule = som.rule
    if som.supervised or len(som.shape) != 2:
        raise ValueError("som_fit_windowed trains unsupervised 2-D maps")
    if max(rule.eta0, rule.eta1) >= 1:
        raise ValueError("som_fit_windowed needs learning rates below 1")
    P, U = som.participants, som.units
    rows, cols = som.shape
    dt = torch.float64
    X = patterns.to(dt)
    X = X.unsqueeze(0).expand(P, -1, -1) if X.dim() == 2 else X
    N = X.shape[1]
    order = torch.as_tensor(order, dtype=torch.long)
    pi = torch.arange(P)
    G = torch.bmm(X, X.transpose(1, 2))  # (P, N, N)
    W0 = som.weight
    # one padding unit (index U) absorbs the window cells that fall off the map
    Q = torch.zeros(P, N, U + 1, dtype=dt)  # Q[p, n, k] = w_k . x_n / c_k (pattern-major: one row per step)
    nrm = torch.zeros(P, U + 1, dtype=dt)
    X32 = X.to(W0.dtype)
    for p in range(P):  # one participant at a time, in the weights' precision (as the online rule)
        Q[p, :, :U] = (X32[p] @ W0[p].T).to(dt)
        nrm[p, :U] = (W0[p] * W0[p]).sum(-1).to(dt)
    c = torch.ones(P, U + 1, dtype=dt)
    f = torch.ones(P, U + 1, dtype=dt)
    R = torch.zeros(P, U + 1, N, dtype=dt)
    grid = som.grid
    reach = float(np.sqrt(2.0 * np.log(1.0 / rule.cutoff))) if rule.cutoff > 0 else float("inf")
    o = torch.arange(-(rows - 1), rows).unsqueeze(1), torch.arange(-(cols - 1), cols).unsqueeze(0)
    offs = torch.stack(torch.broadcast_tensors(*o), -1).reshape(-1, 2)  # every grid offset
    d2_offs = (offs**2).sum(-1).double()
    offs, d2_offs = offs[d2_offs.argsort(stable=True)], d2_offs.sort(stable=True).values  # nearest first
    R_f, nrm_f, c_f = R.view(-1), nrm.view(-1), c.view(-1)
    base = (pi * (U + 1)).unsqueeze(1)
    winners = torch.empty_like(order)
    t0 = int(som.steps)
    for t in range(order.shape[1]):
        s = order[:, t]
        Gs = G[pi, s]  # (P, N)
        Ds = c * Q[pi, s]  # (P, U + 1): w_k . x_s
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
        b = 1 - a
        flat = (idx + base).reshape(-1)  # rows of the flattened (P (U + 1), ...) buffers
        nrm_w, Ds_w, c_w = nrm_f[flat].view(P, -1), Ds.reshape(-1)[flat].view(P, -1), c_f[flat].view(P, -1)
        nrm_f.index_copy_(0, flat, (b * b * nrm_w + 2 * a * b * Ds_w + a * a * Gs[pi, s].unsqueeze(-1)).reshape(-1))
        c_w = b * c_w
        c_f.index_copy_(0, flat, c_w.reshape(-1))
        u = a / c_w  # zero outside the neighbourhood and on the padding unit
        if idx.shape[1] * 2 > U:  # a wide neighbourhood: one contiguous pass over every unit is cheaper
            Q.baddbmm_(Gs.unsqueeze(-1), torch.zeros(P, U + 1, dtype=dt).scatter_(1, idx, u).unsqueeze(1))
        else:
            at = idx.unsqueeze(1).expand(P, N, idx.shape[1])
            Q.scatter_(2, at, Q.gather(2, at).baddbmm_(Gs.unsqueeze(-1), u.unsqueeze(1)))
        R_f.index_add_(0, flat * N + s.repeat_interleave(idx.shape[1]), u.reshape(-1))
        small = c_w < 1e-12  # fold tiny scales back in before they cost precision
        if bool(small.any()):
            pp, kk = small.nonzero(as_tuple=True)
            uu = idx[pp, kk]
            ok = uu < U
            pp, uu = pp[ok], uu[ok]
            cc = c[pp, uu].unsqueeze(-1)
            Q[pp, :, uu] *= cc
            R[pp, uu] *= cc
            f[pp, uu] *= cc.squeeze(-1)
            c[pp, uu] = 1.0
    for p in range(P):  # w_k = c_k f_k W0_k + (c_k R_k) X: coefficients in float64, product in the weights' precision
        cr = (c[p, :U, None] * R[p, :U]).to(W0.dtype)
        som.weight[p].mul_((c[p, :U] * f[p, :U]).to(W0.dtype).unsqueeze(-1)).add_(cr @ X32[p])
    som.steps += order.shape[1]
    return winners
