"""A user's stimuli answered at chance are flagged at the top of the report."""
import numpy as np
import pandas as pd

from neuroimagery.analysis.report import Report
from neuroimagery.analysis.summary import custom_vs_chance


def _trials(rates, n=40, seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for p, r in enumerate(rates):
        correct = rng.permutation(np.arange(n) < round(r * n))
        rows += [dict(participant=p, test="custom", condition="none", correct=bool(c)) for c in correct]
    rows.append(dict(participant=0, test="recog", condition="none", correct=True))
    return pd.DataFrame(rows)


def test_chance_rates_are_flagged_and_good_ones_are_not():
    chance = custom_vs_chance(_trials([0.5, 0.55, 0.45, 0.525, 0.475]))
    good = custom_vs_chance(_trials([0.9, 0.85, 0.95, 0.875, 0.8]))
    assert chance["above_chance"] is False and chance["n"] == 5 and abs(chance["mean_correct"] - 0.5) < 1e-9
    assert good["above_chance"] is True and good["p_greater"] < 0.05
    assert custom_vs_chance(_trials([0.9])[lambda d: d["test"] != "custom"]) is None
    warned = Report("x").chance_warning({"custom_vs_chance": chance}).text()
    assert "answers at chance" in warned and "50.0 %" in warned
    assert "chance" not in Report("x").chance_warning({"custom_vs_chance": good}).text()
    assert "chance" not in Report("x").chance_warning({}).text()
