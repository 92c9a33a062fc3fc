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
