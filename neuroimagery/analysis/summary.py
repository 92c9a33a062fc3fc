"""From ``trials.csv`` rows to the figures of ``summary.json`` (Experiments 1-4), and the
statistics the reports quote.

The participant is the unit of every test of an effect (statsmodels): a paired t-test over the
participants' means, or a one-sample t-test of their slopes, each with its mean and 95 % interval,
the standardised effect size d_z (mean over standard deviation of the participants' values) with
its 95 % interval from the noncentral t distribution, and Holm's correction over each report's
family of effects. Trial-level tests (``compare_rt``, ``compare_rates``) treat trials as
independent samples and are labelled so where reports show them."""
from __future__ import annotations

import math
import warnings
from typing import Iterable

import numpy as np
import pandas as pd

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


def rounded(x: float, nd: int = 4):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else round(float(x), nd)


def rt_profile(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Mean RT per disparity level (sorted)."""
    g = df.groupby("disparity")["rt"].mean().sort_index()
    return g.index.to_numpy(dtype=float), g.to_numpy(dtype=float)


def summarise_test(df: pd.DataFrame) -> dict:
    """The per-test figures of summary.json for the trials of one ``<test>/<condition>``."""
    from scipy import stats

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
        "correct_rate": rounded(correct),
        "error_rate": rounded(1.0 - correct),
        "rotation_success_rate": rounded(float(df["rotated_ok"].astype(float).mean()) if n else float("nan")),
        "rt_mean": rounded(float(df["rt"].mean()) if n else float("nan"), 3),
        "rt_by_disparity": {str(int(round(k))): rounded(v, 3) for k, v in zip(x, y)},
        "error_rate_by_disparity": {str(int(round(k))): rounded(v) for k, v in err.items()},
        "rt_slope_per_deg": rounded(slope),
        "rt_r": rounded(r),
        # where the errors are: NO to same pairs, YES to mirror pairs
        "error_rate_same": rounded(float(wrong[same].mean()) if same.any() else float("nan")),
        "error_rate_different": rounded(float(wrong[~same].mean()) if (~same).any() else float("nan")),
    }


def summarise_trials(df: pd.DataFrame) -> dict:
    """``{"<test>/<condition>": summarise_test(...)}`` over the whole trials table."""
    out = {}
    for (test, cond), g in df.groupby(["test", "condition"], sort=False):
        out[f"{test}/{cond}"] = summarise_test(g)
    return out


def compare_rt(a: Iterable[float], b: Iterable[float]) -> dict:
    """Welch's t-test of two RT samples: means, difference, t and two-sided p."""
    from scipy import stats

    a, b = np.asarray(list(a), float), np.asarray(list(b), float)
    with warnings.catch_warnings():  # two samples of (nearly) one value, as at a ceiling: p is still defined
        warnings.filterwarnings("ignore", "Precision loss occurred", RuntimeWarning)
        t, p = stats.ttest_ind(a, b, equal_var=False)
    return {"mean_a": rounded(a.mean(), 3), "mean_b": rounded(b.mean(), 3), "diff": rounded(a.mean() - b.mean(), 3),
            "t": rounded(t), "p": float(p) if np.isfinite(p) else None, "n_a": int(a.size), "n_b": int(b.size)}


def compare_rates(a: Iterable[bool], b: Iterable[bool]) -> dict:
    """Two proportions compared by a chi-square test (Fisher's exact test for small counts)."""
    from scipy import stats

    a, b = np.asarray(list(a), float), np.asarray(list(b), float)
    table = np.array([[a.sum(), a.size - a.sum()], [b.sum(), b.size - b.sum()]])
    if table.min() < 5:
        _, p = stats.fisher_exact(table)
    else:
        _, p, _, _ = stats.chi2_contingency(table)
    return {"rate_a": rounded(a.mean()), "rate_b": rounded(b.mean()), "diff": rounded(a.mean() - b.mean()), "p": float(p)}


def dz_interval(values: np.ndarray, level: float = 0.95) -> tuple[float, list[float]] | tuple[None, None]:
    """Cohen's d_z of ``values`` (mean / SD) and its ``level`` interval: the noncentrality of the
    noncentral t distribution of the observed t, inverted at both tails, over sqrt(n). Where that
    distribution cannot be evaluated (a very large t with few participants), the large-sample
    interval d +- z sqrt(1/n + d^2 / 2n)."""
    from scipy import optimize, stats

    n = values.size
    if n < 2 or values.std(ddof=1) == 0:
        return None, None
    d = float(values.mean() / values.std(ddof=1))
    t, df, a = d * math.sqrt(n), n - 1, (1 - level) / 2

    def nc_at(q):  # the noncentrality whose t distribution puts the observed t at quantile q
        f = lambda nc: stats.nct.cdf(t, df, nc) - q  # noqa: E731
        w = 6.0 * math.sqrt(1.0 + t * t / (2.0 * df)) + 1.0  # well beyond the interval's half-width
        return optimize.brentq(f, t - w, t + w)

    try:
        lo, hi = nc_at(1 - a) / math.sqrt(n), nc_at(a) / math.sqrt(n)
    except (ValueError, RuntimeError):
        half = stats.norm.ppf(1 - a) * math.sqrt(1 / n + d * d / (2 * n))
        lo, hi = d - half, d + half
    return rounded(d, 4), [rounded(lo, 4), rounded(hi, 4)]


def one_sample(values, test_value: float = 0.0) -> dict:
    """t-test of ``values`` (one per participant) against ``test_value`` (statsmodels): mean, its
    95 % interval, t, two-sided p, d_z and its 95 % interval."""
    from statsmodels.stats.weightstats import DescrStatsW

    v = np.asarray(values, float)
    out = {"n": int(v.size), "mean": rounded(v.mean(), 5) if v.size else None, "t": None, "p": None, "ci95": None,
           "d_z": None, "d_z_ci95": None, "sd": float(v.std(ddof=1)) if v.size >= 2 else None}
    if v.size >= 2 and v.std(ddof=1) > 0:
        ds = DescrStatsW(v)
        t, p, _ = ds.ttest_mean(test_value)
        lo, hi = ds.tconfint_mean(0.05)
        d, dci = dz_interval(v - test_value)
        out.update(t=rounded(t), p=float(p), ci95=[rounded(lo, 5), rounded(hi, 5)], d_z=d, d_z_ci95=dci)
    elif v.size >= 2:  # every participant alike: no spread to test against
        m = float(v.mean())
        out.update(p=1.0 if m == test_value else 0.0, ci95=[rounded(m, 5), rounded(m, 5)])
    return out


def paired_by_participant(a: pd.DataFrame, b: pd.DataFrame, value: str) -> dict:
    """The participant as the unit: each participant's mean of ``value`` in ``a`` and in ``b``,
    compared by a paired t-test over the participants present in both (two-sided p), with the
    mean difference ``a - b``, its 95 % interval and d_z."""
    return paired_means(a.groupby("participant")[value].mean(), b.groupby("participant")[value].mean())


def paired_means(ma: pd.Series, mb: pd.Series) -> dict:
    """:func:`paired_by_participant` of the participants' means ``ma`` and ``mb`` (Series indexed
    by participant)."""
    both = ma.index.intersection(mb.index)
    x, y = ma.loc[both].to_numpy(float), mb.loc[both].to_numpy(float)
    res = one_sample(x - y)
    res["diff"] = rounded(res.pop("mean"), 4) if res["mean"] is not None else None
    res.update(mean_a=rounded(x.mean(), 4) if x.size else None, mean_b=rounded(y.mean(), 4) if y.size else None)
    if res["ci95"]:
        res["ci95"] = [rounded(c, 4) for c in res["ci95"]]
    return res


def slope_by_participant(df: pd.DataFrame, x: str = "disparity", y: str = "rt") -> dict:
    """Each participant's least-squares slope of ``y`` on ``x``, and a one-sample t-test of the
    slopes against 0 over the participants (the participant as the unit)."""
    slopes = []
    for _, g in df.groupby("participant"):
        xs, ys = g[x].to_numpy(float), g[y].to_numpy(float)
        if np.ptp(xs) > 0:
            slopes.append(float(np.polyfit(xs, ys, 1)[0]))
    res = one_sample(slopes)
    res["mean_slope"] = res.pop("mean")
    return res


def repeated_anova(df: pd.DataFrame, factor: str, value: str = "rt") -> dict:
    """One-way repeated-measures ANOVA of the participants' mean ``value`` per level of ``factor``
    (statsmodels ``AnovaRM``; the participant as the unit): F, its degrees of freedom and p."""
    from statsmodels.stats.anova import AnovaRM

    cell = df.groupby(["participant", factor], as_index=False)[value].mean()
    full = cell.groupby("participant")[factor].nunique() == cell[factor].nunique()
    cell = cell[cell["participant"].isin(full[full].index)]
    out = {"factor": factor, "n": int(cell["participant"].nunique()), "F": None, "df": None, "p": None}
    if out["n"] < 2 or cell[factor].nunique() < 2 or cell[value].std() == 0:
        return out
    res = AnovaRM(cell, value, "participant", within=[factor]).fit().anova_table.iloc[0]
    if np.isfinite(res["F Value"]):
        out.update(F=rounded(res["F Value"]), df=[int(res["Num DF"]), int(res["Den DF"])], p=float(res["Pr > F"]))
    return out


DEGENERATE_DZ = 10.0  # |d_z| above this: the participants' SD is below a tenth of the mean (docs/choices.md)


def tost(mean: float | None, sd: float | None, n: int | None, bound: float) -> float | None:
    """Two one-sided t-tests of a mean (participants' values: ``mean``, ``sd``, ``n``) against the
    equivalence bounds ``-bound`` and ``+bound``: the larger one-sided p (statsmodels'
    ``DescrStatsW.ttost_mean`` from the summary figures). Equivalence at level alpha when it is
    below alpha. With no spread, 0 inside the bounds and 1 outside; None when nothing to test."""
    from scipy import stats

    if mean is None or n is None or n < 2 or sd is None or not bound > 0:
        return None
    if sd == 0:
        return 0.0 if abs(mean) < bound else 1.0
    se = sd / math.sqrt(n)
    p_low = stats.t.sf((mean + bound) / se, n - 1)  # H0: mean <= -bound
    p_upp = stats.t.cdf((mean - bound) / se, n - 1)  # H0: mean >= +bound
    return float(max(p_low, p_upp))


def effect(name: str, expected: str, res: dict, key: str = "diff", bound: float | None = None) -> dict:
    """One row of a report's effects table: ``expected`` is ``'>0'``, ``'<0'`` or ``'~0'`` for the
    value ``res[key]`` (a paired difference or a mean slope). A signed effect holds with the
    expected sign and p < 0.05 (two-sided t-test; Holm's correction in :func:`holm`). A ``'~0'``
    claim is an equivalence test (:func:`tost`) within ``+-bound`` (a rule of docs/choices.md):
    ``p`` is the TOST p (``p_difference`` keeps the two-sided difference test's), and it holds
    ("equivalent within +-bound") when that p is below 0.05; without a bound it is not tested
    (``p`` None, ``holds`` None: "not shown"). ``d_z_degenerate``: |d_z| > ``DEGENERATE_DZ``."""
    v, p = res.get(key), res.get("p")
    row = {"effect": name, "expected": expected, "value": v, "ci95": res.get("ci95"), "p": p, "n": res.get("n"),
           "d_z": res.get("d_z"), "d_z_ci95": res.get("d_z_ci95"),
           "d_z_degenerate": res.get("d_z") is not None and abs(res["d_z"]) > DEGENERATE_DZ}
    if res.get("untested"):  # why no test could be made (e.g. a group at 0 % or 100 %)
        row["untested"] = res["untested"]
    if expected == "~0":
        row.update(bound=bound, p_difference=p, test="TOST")
        if bound is None:
            p = None
        else:
            p = res["p_tost"] if "p_tost" in res else tost(v, res.get("sd"), res.get("n"), bound)
        row["p"] = p
        holds = None if p is None or bound is None else p < 0.05
    elif v is None or p is None:
        holds = None
    else:
        holds = (v > 0 if expected == ">0" else v < 0) and p < 0.05
    row["holds"] = holds
    return row


def equivalent_levels(df: pd.DataFrame, factor: str, value: str, bound: float) -> dict:
    """No effect of ``factor`` on ``value`` as an intersection-union test: every pair of its levels
    compared on the participants' means (paired), each by :func:`tost` within ``+-bound``; the
    claim's p is the largest pairwise TOST p. ``diff`` is the largest absolute pairwise mean
    difference, ``ci95`` that pair's interval, ``p`` the smallest two-sided pairwise p."""
    levels = list(dict.fromkeys(df[factor]))
    worst = {"n": int(df["participant"].nunique()), "diff": None, "ci95": None, "p": None, "p_tost": None, "sd": None}
    if len(levels) < 2:
        return worst
    p_tost, p_diff = [], []
    for i, a in enumerate(levels):
        for b in levels[i + 1:]:
            r = paired_by_participant(df[df[factor] == a], df[df[factor] == b], value)
            pt = tost(r["diff"], r["sd"], r["n"], bound)
            p_tost.append(1.0 if pt is None else pt)
            if r["p"] is not None:
                p_diff.append(r["p"])
            if r["diff"] is not None and (worst["diff"] is None or abs(r["diff"]) > abs(worst["diff"])):
                worst.update(diff=r["diff"], ci95=r["ci95"], n=r["n"], sd=r["sd"])
    worst.update(p_tost=max(p_tost), p=min(p_diff) if p_diff else None)
    return worst


def holm_adjusted(p) -> np.ndarray:
    """Holm's step-down adjusted p-values of ``p``, the arithmetic of statsmodels'
    ``multipletests(p, method="holm")[1]`` (sorted p times n, n - 1, ..., 1, running maximum, at
    most 1, back in the given order) without the full garbage collection that function runs on
    every call."""
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    adj = np.maximum.accumulate(np.take(p, order) * np.arange(len(p), 0, -1))
    adj[adj > 1] = 1
    out = np.empty_like(adj)
    out[order] = adj
    return out


def holm(rows: list[dict]) -> list[dict]:
    """Add ``p_holm``: Holm's step-down correction (:func:`holm_adjusted`) over the family
    ``rows`` (their ``p``: the two-sided p of a signed effect, the TOST p of a ``'~0'`` claim);
    every claim then holds on the corrected p."""
    idx = [i for i, r in enumerate(rows) if r.get("p") is not None]
    if idx:
        adj = holm_adjusted([rows[i]["p"] for i in idx])
        for i, q in zip(idx, adj):
            rows[i]["p_holm"] = float(q)
    for r in rows:
        if r.get("holds") is None:
            continue
        if r["expected"] == "~0":
            r["holds"] = bool(r["p_holm"] < 0.05)
        else:
            r["holds"] = bool((r["value"] > 0 if r["expected"] == ">0" else r["value"] < 0) and r["p_holm"] < 0.05)
    return rows


def custom_vs_chance(df: pd.DataFrame) -> dict | None:
    """A user's stimuli (test ``custom``, condition ``none``) against chance: each participant's
    correct rate, a one-sided one-sample t-test of the rates against 0.5 over the participants.
    ``above_chance`` is a mean above 0.5 with p < 0.05. None when the run has no custom test."""
    from scipy import stats

    c = df[(df["test"] == "custom") & (df["condition"] == "none")]
    if c.empty:
        return None
    rates = c.groupby("participant")["correct"].mean().to_numpy(float)
    out = {"n": int(rates.size), "mean_correct": rounded(rates.mean(), 4), "t": None, "p_greater": None,
           "above_chance": False}
    if rates.size >= 2 and rates.std(ddof=1) > 0:
        t, p = stats.ttest_1samp(rates, 0.5, alternative="greater")
        out.update(t=rounded(t), p_greater=float(p), above_chance=bool(rates.mean() > 0.5 and p < 0.05))
    elif rates.size >= 1:
        out["above_chance"] = bool(rates.min() > 0.5 and rates.size >= 2)
    return out


HEADLINE_KEYS = ("correct_rate", "error_rate", "rotation_success_rate", "rt_mean", "rt_slope_per_deg", "rt_r")


def headline(summary: dict) -> dict:
    """The figures a sweep compares (TensorBoard's HParams view): ``<test>/<key>`` for the per-test
    ``HEADLINE_KEYS`` of ``summary["tests"]``, and the summary's own top-level numbers."""
    out = {k: v for k, v in summary.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    for test, t in (summary.get("tests") or {}).items():
        if isinstance(t, dict):
            out.update({f"{test}/{k}": t[k] for k in HEADLINE_KEYS
                        if isinstance(t.get(k), (int, float)) and not isinstance(t.get(k), bool)})
    return out
