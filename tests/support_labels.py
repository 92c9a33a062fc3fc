"""The label test: after the protocol has chosen its trials, every label column of the trial table
(angles, appearances, objects, same/mirror, disparity) is overwritten with shuffled values while the
images stay; a model that reads only the images gives the same answers and RTs."""
from __future__ import annotations

import numpy as np
import pandas as pd

KEEP = ("test", "condition", "target_row", "rotated_row")  # what says which images a trial shows


def shuffle_labels(table: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """``table`` with each label column permuted independently (the image rows kept)."""
    rng = np.random.default_rng(seed)
    out = table.copy()
    cols = [c for c in table.columns if c not in KEEP]
    assert {"rotated_angle", "target_object", "rotated_object"} <= set(cols), cols
    for c in cols:
        out[c] = table[c].to_numpy()[rng.permutation(len(table))]
    assert any((out[c] != table[c]).any() for c in cols)  # the labels did change
    return out


def shuffle_pair_labels(pairs: list[dict], seed: int = 0) -> list[dict]:
    """The same for a list of pair dicts (Exp. 1): each key's values permuted across the pairs."""
    frame = pd.DataFrame(pairs)
    return shuffle_labels(frame.assign(target_row=0, rotated_row=0), seed).drop(
        columns=["target_row", "rotated_row"]).to_dict("records")


def answers(df: pd.DataFrame) -> pd.DataFrame:
    """The model's outputs of a trials table, in trial order."""
    cols = [c for c in ("participant", "condition", "answer", "rt", "rotation_steps") if c in df.columns]
    return df[cols].reset_index(drop=True)


def assert_run_tests_read_no_labels(monkeypatch, module, cfg, model, tables=None, moved: str = "target_angle") -> None:
    """Exp. 3-4 (and 6): ``module.run_tests`` on the chosen trials, then on the same trials with every
    label column shuffled (``tables.trial_table`` wrapped; ``protocol_ch6`` by default): the outputs
    are identical, while the label column ``moved`` did change."""
    if tables is None:
        from neuroimagery.experiments.chapter6 import protocol as tables

    base, _, _ = module.run_tests(cfg, model)
    original = tables.trial_table
    monkeypatch.setattr(tables, "trial_table", lambda *a, **k: shuffle_labels(original(*a, **k), seed=7))
    shuffled, _, _ = module.run_tests(cfg, model)
    assert (shuffled[moved].to_numpy() != base[moved].to_numpy()).any()
    pd.testing.assert_frame_equal(answers(shuffled), answers(base))
