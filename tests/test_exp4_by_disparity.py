"""Exp 4's table "proprioception by disparity": the participant is the unit (paired t-tests of the
participants' means) and every p of the table is Holm-corrected over the table."""
import numpy as np
import pandas as pd
from scipy import stats
from statsmodels.stats.multitest import multipletests

from neuroimagery.experiments.exp4.protocol import _stats_by_disparity


def _trials(seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for p in range(6):
        for cond, shift in (("none", 0.0), ("mismatch", 4.0), ("match", -1.0)):
            for disp in (0, 60, 120):
                for k in range(5):  # five trials of a participant: one unit, not five
                    rows.append({"participant": p, "test": "recog", "condition": cond, "disparity": disp,
                                 "rt": 20 + disp / 10 + shift * (disp > 0) + rng.normal(0, 2),
                                 "correct": bool(rng.random() < 0.9 - 0.1 * (cond == "mismatch"))})
    return pd.DataFrame(rows)


def test_by_disparity_tests_participants_and_corrects_over_the_table():
    df = _trials()
    out = _stats_by_disparity(df)
    assert set(out) == {"recog:match-vs-none", "recog:mismatch-vs-none"}
    row = out["recog:mismatch-vs-none"]["120"]
    a = df[(df["condition"] == "mismatch") & (df["disparity"] == 120)].groupby("participant")["rt"].mean()
    b = df[(df["condition"] == "none") & (df["disparity"] == 120)].groupby("participant")["rt"].mean()
    assert row["n"] == 6 and np.isclose(row["rt_p"], stats.ttest_rel(a, b).pvalue)
    ps = [(r, k) for rows in out.values() for r in rows.values() for k in ("rt", "correct") if r[f"{k}_p"] is not None]
    want = multipletests([r[f"{k}_p"] for r, k in ps], method="holm")[1]
    assert len(ps) >= 10 and np.allclose([r[f"{k}_p_holm"] for r, k in ps], want)
    assert all(r[f"{k}_p_holm"] >= r[f"{k}_p"] for r, k in ps)
