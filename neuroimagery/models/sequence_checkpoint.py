"""Compact checkpoints of the Experiment 4 model: its three forward models C1-C3 (``fm.0-2``,
``(P, n, n)`` weights each, nearly all of the model's size) are a fixed function of their initial
weights and of the three-dot training sequence they learnt from by the delta rule. The checkpoint
stores that sequence, each 0/1 image as the list of its active units (about 15 of ``n = 1024``),
with the drawn movements and the mini-batch size, and the model's other tensors as they are; the
initial weights are drawn again from the run's seed when the model is built. Loading replays the
training (:meth:`RotationEmbodied.fit_forward_models`, the same kernel on the same inputs) and
checks the first and last row of each rebuilt weight against the trained ones, which it stores
(``probe``): they must be equal, or the load is refused (the full form, a ``state_dict``, loads
on any machine).

A model records its sequence in :attr:`fm_sequence` while it trains (:func:`record`), so only
a model trained in this process can be saved in compact form.
"""
from __future__ import annotations

import torch

from ..nn import binary
from ..nn.binary import ActiveRows

FORMAT = "exp4-compact-1"
PROBE_ROWS = [0, -1]  # the rows of each rebuilt weight compared on load
KEYS = tuple(f"fm.{m}.weight" for m in range(3))


def active_units(X: torch.Tensor) -> torch.Tensor:
    """0/1 images ``(P, N, n)`` -> the indices of their active units ``(P, N, D)`` (int16, -1
    pads an image with fewer than ``D`` active units; :func:`neuroimagery.nn.binary.active_units`);
    a ValueError unless ``X`` is 0/1."""
    try:
        return binary.active_units(X)
    except ValueError as err:
        raise ValueError(f"the compact checkpoint stores 0/1 images only ({err})") from err


def from_active(idx: torch.Tensor, n: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """The 0/1 images ``(P, N, n)`` of :func:`active_units`' indices."""
    return ActiveRows(idx, n, dtype).rows(0, idx.shape[1]).contiguous()


def record(X: ActiveRows, Y: ActiveRows, moves: torch.Tensor, batch: int) -> dict:
    """The forward models' training sequence (inputs and targets by their active units) in the
    checkpoint's form."""
    return {"pre": X.index.to(torch.int16), "target": Y.index.to(torch.int16), "moves": moves.to(torch.int8),
            "batch": int(batch), "units": int(X.width)}


def compact_state(model) -> dict:
    """``model``'s trained state in compact form (see the module docstring)."""
    seq = getattr(model, "fm_sequence", None)
    if seq is None:
        raise ValueError("a compact checkpoint needs a model trained by fit_forward_models() in this process")
    state = model.state_dict()
    return {"format": FORMAT, "participants": list(model.participant_ids), "fm_training": dict(seq),
            "state": {k: v for k, v in state.items() if k not in KEYS},
            "probe": {k: state[k][:, PROBE_ROWS].clone() for k in KEYS}}


@torch.no_grad()
def load_compact_state(model, ck: dict) -> None:
    """Load a :func:`compact_state` into a *freshly built* model (the checkpoint's participants,
    the run's seed and settings: its initial weights are where the replay starts); returns it in
    ``eval()`` mode. A ValueError when the state does not fit or a rebuilt weight differs from
    the trained one."""
    if ck.get("format") != FORMAT:
        raise ValueError(f"unknown checkpoint format {ck.get('format')!r} (this model reads {FORMAT!r})")
    seq = ck["fm_training"]
    n = int(seq["units"])
    if seq["pre"].shape[0] != model.participants or n != model.n:
        raise ValueError(f"its training sequence is of {seq['pre'].shape[0]} participants and maps of {n} units, "
                         f"the model of {model.participants} participants and maps of {model.n} units")
    model.fit_forward_models(ActiveRows(seq["pre"], n), ActiveRows(seq["target"], n), seq["moves"].long(),
                             int(seq["batch"]))
    res = model.load_state_dict(ck["state"], strict=False)
    if set(res.missing_keys) != set(KEYS) or res.unexpected_keys:
        raise ValueError(f"checkpoint state does not fit the model: missing {sorted(set(res.missing_keys) - set(KEYS))}, "
                         f"unexpected {res.unexpected_keys}")
    state = model.state_dict()
    bad = [k for k, v in ck["probe"].items() if not torch.equal(state[k][:, PROBE_ROWS], v)]
    if bad:
        raise ValueError(f"the forward-model weights formed again from the stored training sequence differ from the "
                         f"trained ones ({', '.join(bad)}): this machine forms them differently, or the checkpoint "
                         "was trained with other settings; use a checkpoint in full form")
    model.eval()
