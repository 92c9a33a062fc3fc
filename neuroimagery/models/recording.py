"""Which trials a model's run returns step by step (sample trials for figures and TensorBoard)."""
from __future__ import annotations


def sample_indices(record, trials: int) -> list[int]:
    """The trials whose maps a run returns step by step: ``record`` leading trials (an int) or the
    given trial indices (any that exist), in the order given."""
    if isinstance(record, int):
        return list(range(min(record, trials)))
    return [int(k) for k in record if 0 <= int(k) < trials]
