"""From ``trials.csv`` rows to the figures of ``summary.json`` (Experiments 1-4), and the
statistics the reports quote."""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np
import pandas as pd
from scipy import stats

TRIAL_COLUMNS = [
    "participant", "test", "condition", "target_object", "target_angle", "target_appearance",
    "rotated_object", "rotated_angle", "rotated_appearance", "disparity", "same", "answer", "correct",
    "rotation_steps", "rotated_ok", "rt",
]


def check_trials(df: pd.DataFrame) -> pd.DataFrame:
    """Raise ValueError naming the missing columns of a trials table; returns it ordered."""
    missing = [c for c in TRIAL_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"trials table lacks columns {missing}")
    extra = [c for c in df.columns if c not in TRIAL_COLUMNS]
    return df[TRIAL_COLUMNS + extra]


def _r(x: float, nd: int = 4):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else round(float(x), nd)


def rt_profile(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Mean RT per disparity level (sorted)."""
    g = df.groupby("disparity")["rt"].mean().sort_index()
    return g.index.to_numpy(dtype=float), g.to_numpy(dtype=float)


def summarise_test(df: pd.DataFrame) -> dict:
    """The per-test figures of summary.json for the trials of one ``<test>/<condition>``."""
    n = len(df)
    correct = float(df["correct"].astype(float).mean()) if n else float("nan")
    x, y = rt_profile(df)
    if len(x) >= 2 and np.ptp(y) > 0:
        slope, _, r, _, _ = stats.linregress(x, y)
    else:
        slope, r = (0.0 if len(x) >= 2 else float("nan")), float("nan")
    err = df.groupby("disparity")["correct"].apply(lambda c: 1.0 - c.astype(float).mean()).sort_index()
    same = df["same"].astype(bool) if n else df["same"]
    wrong = ~df["correct"].astype(bool) if n else df["correct"]
    return {
        "n_trials": int(n),
        "correct_rate": _r(correct),
        "error_rate": _r(1.0 - correct),
        "rotation_success_rate": _r(float(df["rotated_ok"].astype(float).mean()) if n else float("nan")),
        "rt_mean": _r(float(df["rt"].mean()) if n else float("nan"), 3),
        "rt_by_disparity": {str(int(round(k))): _r(v, 3) for k, v in zip(x, y)},
        "error_rate_by_disparity": {str(int(round(k))): _r(v) for k, v in err.items()},
        "rt_slope_per_deg": _r(slope),
        "rt_r": _r(r),
        # where the errors are: NO to same pairs, YES to mirror pairs
        "error_rate_same": _r(float(wrong[same].mean()) if same.any() else float("nan")),
        "error_rate_different": _r(float(wrong[~same].mean()) if (~same).any() else float("nan")),
    }


def summarise_trials(df: pd.DataFrame) -> dict:
    """``{"<test>/<condition>": summarise_test(...)}`` over the whole trials table."""
    out = {}
    for (test, cond), g in df.groupby(["test", "condition"], sort=False):
        out[f"{test}/{cond}"] = summarise_test(g)
    return out


def compare_rt(a: Iterable[float], b: Iterable[float]) -> dict:
    """Welch's t-test of two RT samples: means, difference, t and two-sided p."""
    a, b = np.asarray(list(a), float), np.asarray(list(b), float)
    t, p = stats.ttest_ind(a, b, equal_var=False)
    return {"mean_a": _r(a.mean(), 3), "mean_b": _r(b.mean(), 3), "diff": _r(a.mean() - b.mean(), 3),
            "t": _r(t), "p": float(p) if np.isfinite(p) else None, "n_a": int(a.size), "n_b": int(b.size)}


def compare_rates(a: Iterable[bool], b: Iterable[bool]) -> dict:
    """Two proportions compared by a chi-square test (Fisher's exact test for small counts)."""
    a, b = np.asarray(list(a), float), np.asarray(list(b), float)
    table = np.array([[a.sum(), a.size - a.sum()], [b.sum(), b.size - b.sum()]])
    if table.min() < 5:
        _, p = stats.fisher_exact(table)
    else:
        _, p, _, _ = stats.chi2_contingency(table)
    return {"rate_a": _r(a.mean()), "rate_b": _r(b.mean()), "diff": _r(a.mean() - b.mean()), "p": float(p)}


def paired_by_participant(a: pd.DataFrame, b: pd.DataFrame, value: str) -> dict:
    """The participant as the unit: each participant's mean of ``value`` in ``a`` and in ``b``,
    compared by a paired t-test over the participants present in both (two-sided p), with the
    mean difference ``a - b`` and its 95 % interval."""
    ma = a.groupby("participant")[value].mean()
    mb = b.groupby("participant")[value].mean()
    both = ma.index.intersection(mb.index)
    x, y = ma.loc[both].to_numpy(float), mb.loc[both].to_numpy(float)
    d = x - y
    out = {"n": int(d.size), "mean_a": _r(x.mean(), 4) if d.size else None, "mean_b": _r(y.mean(), 4) if d.size else None,
           "diff": _r(d.mean(), 4) if d.size else None, "t": None, "p": None, "ci95": None}
    if d.size >= 2 and d.std(ddof=1) > 0:
        t, p = stats.ttest_rel(x, y)
        half = stats.t.ppf(0.975, d.size - 1) * d.std(ddof=1) / math.sqrt(d.size)
        out.update(t=_r(t), p=float(p), ci95=[_r(d.mean() - half, 4), _r(d.mean() + half, 4)])
    elif d.size >= 2:
        out.update(p=1.0 if d.mean() == 0 else 0.0, ci95=[_r(d.mean(), 4), _r(d.mean(), 4)])
    return out


def slope_by_participant(df: pd.DataFrame, x: str = "disparity", y: str = "rt") -> dict:
    """Each participant's least-squares slope of ``y`` on ``x``, and a one-sample t-test of the
    slopes against 0 over the participants (the participant as the unit)."""
    slopes = []
    for _, g in df.groupby("participant"):
        xs, ys = g[x].to_numpy(float), g[y].to_numpy(float)
        if np.ptp(xs) > 0:
            slopes.append(float(np.polyfit(xs, ys, 1)[0]))
    s = np.asarray(slopes)
    out = {"n": int(s.size), "mean_slope": _r(s.mean(), 5) if s.size else None, "t": None, "p": None}
    if s.size >= 2 and s.std(ddof=1) > 0:
        t, p = stats.ttest_1samp(s, 0.0)
        out.update(t=_r(t), p=float(p))
    return out


def effect(name: str, expected: str, res: dict, key: str = "diff") -> dict:
    """One row of a report's effects table: ``expected`` is ``'>0'``, ``'<0'`` or ``'~0'`` for the
    value ``res[key]`` (a paired difference or a mean slope); ``holds`` says whether the measured
    value has the expected sign and, for a signed effect, p < 0.05 (``'~0'``: p >= 0.05)."""
    v, p = res.get(key), res.get("p")
    if v is None or p is None:
        holds = None
    elif expected == "~0":
        holds = p >= 0.05
    else:
        holds = (v > 0 if expected == ">0" else v < 0) and p < 0.05
    return {"effect": name, "expected": expected, "value": v, "ci95": res.get("ci95"), "p": p, "n": res.get("n"),
            "holds": holds}


def holm(rows: list[dict]) -> list[dict]:
    """Add ``p_holm``: Holm's step-down correction over the family ``rows`` (their ``p``)."""
    ps = [(r["p"], i) for i, r in enumerate(rows) if r.get("p") is not None]
    ps.sort()
    m, running = len(ps), 0.0
    for rank, (p, i) in enumerate(ps):
        running = max(running, min(1.0, (m - rank) * p))
        rows[i]["p_holm"] = running
    for r in rows:  # a signed effect holds on the corrected p; '~0' keeps the uncorrected (stricter) one
        if r.get("holds") is not None and r["expected"] != "~0":
            r["holds"] = bool((r["value"] > 0 if r["expected"] == ">0" else r["value"] < 0) and r["p_holm"] < 0.05)
    return rows


def custom_vs_chance(df: pd.DataFrame) -> dict | None:
    """A user's stimuli (test ``custom``, condition ``none``) against chance: each participant's
    correct rate, a one-sided one-sample t-test of the rates against 0.5 over the participants.
    ``above_chance`` is a mean above 0.5 with p < 0.05. None when the run has no custom test."""
    c = df[(df["test"] == "custom") & (df["condition"] == "none")]
    if c.empty:
        return None
    rates = c.groupby("participant")["correct"].mean().to_numpy(float)
    out = {"n": int(rates.size), "mean_correct": _r(rates.mean(), 4), "t": None, "p_greater": None,
           "above_chance": False}
    if rates.size >= 2 and rates.std(ddof=1) > 0:
        t, p = stats.ttest_1samp(rates, 0.5, alternative="greater")
        out.update(t=_r(t), p_greater=float(p), above_chance=bool(rates.mean() > 0.5 and p < 0.05))
    elif rates.size >= 1:
        out["above_chance"] = bool(rates.min() > 0.5 and rates.size >= 2)
    return out
