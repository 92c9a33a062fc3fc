"""Which trials a model's run returns step by step (sample trials for figures and TensorBoard)."""
from __future__ import annotations

import torch


def sample_indices(record, trials: int) -> list[int]:
    """The trials whose maps a run returns step by step: ``record`` leading trials (an int) or the
    given trial indices (any that exist), in the order given."""
    if isinstance(record, int):
        return list(range(min(record, trials)))
    return [int(k) for k in record if 0 <= int(k) < trials]


def first_rows(rows, rec) -> list[tuple[int, int]]:
    """``(position, slot)`` for each ``(trial, slot)`` of ``rec`` whose trial is among ``rows``
    (a long tensor of trial indices): the first position holding it, found in one pass over
    ``rows`` (its positions ascending)."""
    if not rec:
        return []
    slots: dict[int, list[int]] = {}
    for trial, slot in rec:
        slots.setdefault(int(trial), []).append(slot)
    out, seen = [], set()
    for i in torch.isin(rows, torch.tensor(list(slots), dtype=rows.dtype)).nonzero().squeeze(-1).tolist():
        trial = int(rows[i])
        if trial not in seen:
            seen.add(trial)
            out += [(i, slot) for slot in slots[trial]]
    return out

