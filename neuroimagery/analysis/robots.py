"""Experiment 5's effects with the simulated robot as the unit (statsmodels).

Each row of ``individuals.csv`` is one robot's test (success 0/1). The thesis's effects (section
7.1.3) are tested on those rows:

* a rise with age (HP1, tool far) or with training (HP2): a logistic regression of success on the
  group's level (or on trained vs untrained), the value its log-odds slope per level (or the log
  odds ratio), with a 95 % interval and a two-sided Wald p. The robots of one repetition share
  one skill library across the groups, so the standard errors are cluster-robust over the
  libraries (``cov_type='cluster'``); a fit that does not converge (a group at 0 % or 100 %) is
  reported without a p;
* reactive against planning children: the same robots tested both ways, paired by robot and
  group: McNemar's exact test of the discordant pairs, the value the difference of success rates
  with a Wald 95 % interval of the paired difference;

with Holm's correction over the family (:func:`neuroimagery.analysis.summary.holm`). A pooled table
of several runs keys robots and libraries by run, so no two runs share a unit.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd

from .summary import effect, holm, rounded

ROBOT_EFFECTS_INTRO = ("Each effect is tested with the simulated robot as the unit (statsmodels): a rise with age or "
                       "with training is a logistic regression of each robot's success on the group's level (value: "
                       "the log-odds per level, or the log odds ratio of trained against untrained robots), with "
                       "standard errors cluster-robust over the skill libraries the groups share; reactive against "
                       "planning pairs each robot's two tests (value: the difference of success rates, McNemar's "
                       "exact p). 95 % intervals; p (Holm) corrects over the rows of this table. 'holds': the "
                       "expected sign with p (Holm) < 0.05. A row without a test ('-') says why under the table.")
ROBOT_EQUIVALENCE = ("A claim of no effect ('~0') is tested by equivalence: two one-sided z-tests of the paired "
                     "difference of success rates (its Wald standard error) against -B and +B, B = 5 points of a "
                     "rate, fixed before measuring (docs/choices.md, 'Statistics in the reports'); its p is the "
                     "larger one-sided p, Holm-corrected with the rest. It reads 'equivalent within ±B' when p "
                     "(Holm) < 0.05 and 'not shown' otherwise: a large p of a difference test is never read as no "
                     "effect.")


def _units(df: pd.DataFrame) -> pd.DataFrame:
    run = df["run"].astype(str) + "/" if "run" in df else ""
    return df.assign(_robot=run + df["individual"].astype(str), _library=run + df["library"].astype(str))


def logistic_trend(df: pd.DataFrame, x: str) -> dict:
    """Logistic regression ``success ~ x`` over the rows ``df`` (cluster-robust by library):
    ``value`` the coefficient of ``x`` (log-odds per unit), ``ci95``, ``p``, ``n`` robots."""
    import statsmodels.api as sm

    d = _units(df)
    out = {"n": int(d["_robot"].nunique()), "diff": None, "ci95": None, "p": None}
    y, xs = d["success"].astype(float).to_numpy(), d[x].astype(float).to_numpy()
    counts = ", ".join(f"{x} {k:g}: {int(g['success'].sum())} of {len(g)} succeed" for k, g in d.groupby(x))
    if len(d) < 4 or np.ptp(xs) == 0:
        out["untested"] = f"too few robots or one {x} level only ({counts})"
        return out
    if y.min() == y.max():
        out["untested"] = f"every robot {'succeeds' if y[0] else 'fails'}, so no rate can differ ({counts})"
        return out
    groups = pd.factorize(d["_library"])[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # perfect separation and small clusters: judged below
        try:
            fit = sm.GLM(y, sm.add_constant(xs), family=sm.families.Binomial()).fit(
                cov_type="cluster", cov_kwds={"groups": groups})
        except Exception:  # noqa: BLE001 - a singular fit is reported without a test
            out["untested"] = f"the regression has no fit ({counts})"
            return out
    b, (lo, hi), p = fit.params[1], fit.conf_int()[1], fit.pvalues[1]
    if not all(map(math.isfinite, (b, lo, hi, p))) or abs(b) > 20:
        out["untested"] = f"a group at 0 % or 100 % separates the outcomes: the log odds have no finite estimate ({counts})"
        return out
    if not fit.bse[1] > 0:
        out["untested"] = f"no spread between the skill libraries, so no cluster-robust error ({counts})"
        return out
    out.update(diff=rounded(b, 4), ci95=[rounded(lo, 4), rounded(hi, 4)], p=float(p))
    return out


EQUIVALENCE_BOUND = 0.05  # "alike": within 5 points of a rate (docs/choices.md)


def _tost_wald(diff: float, se: float, bound: float) -> float:
    """Two one-sided z-tests of a paired difference of rates (its Wald standard error ``se``)
    against ``-bound`` and ``+bound``: the larger one-sided p."""
    from scipy import stats

    if se == 0:
        return 0.0 if abs(diff) < bound else 1.0
    return float(max(stats.norm.sf((diff + bound) / se), stats.norm.cdf((diff - bound) / se)))


def paired_strategies(df: pd.DataFrame) -> dict:
    """Reactive minus planning success over the robots tested both ways in the same group:
    ``value`` the difference of rates, its Wald 95 % interval, McNemar's exact p, ``n`` pairs."""
    from statsmodels.stats.contingency_tables import mcnemar

    d = _units(df)
    keys = ["_robot", "hypothesis", "level", "situation"]
    wide = d.pivot_table(index=keys, columns="strategy", values="success", aggfunc="first")
    out = {"n": 0, "diff": None, "ci95": None, "p": None}
    if not {"reactive", "planning"} <= set(wide.columns):
        return out
    wide = wide.dropna(subset=["reactive", "planning"])
    r, q = wide["reactive"].astype(int).to_numpy(), wide["planning"].astype(int).to_numpy()
    n = r.size
    out["n"] = int(n)
    if n == 0:
        return out
    b, c = int(((r == 1) & (q == 0)).sum()), int(((r == 0) & (q == 1)).sum())
    diff = (b - c) / n
    se = math.sqrt(max(b + c - (b - c) ** 2 / n, 0.0)) / n
    out.update(diff=rounded(diff, 4), ci95=[rounded(diff - 1.96 * se, 4), rounded(diff + 1.96 * se, 4)],
               p=float(mcnemar([[0, b], [c, 0]], exact=True).pvalue) if b + c else 1.0,
               p_tost=_tost_wald(diff, se, EQUIVALENCE_BOUND))
    return out


def effects(df: pd.DataFrame, hp1_levels, hp2_trials, strategies=("reactive", "planning")) -> list[dict]:
    """The effects of thesis section 7.1.3 on the rows of individuals.csv, the robot as the unit."""
    rows = []
    for strat in strategies:
        s = df[df["strategy"] == strat]
        far = s[(s["hypothesis"] == "hp1") & (s["situation"] == "far") & s["level"].isin(hp1_levels)]
        if far["level"].nunique() > 1:
            rows.append(effect(f"HP1 tool far rises with age ({strat}; log-odds per level)", ">0",
                               logistic_trend(far, "level")))
        for sit in ("behind", "far"):
            h = s[(s["hypothesis"] == "hp2") & (s["situation"] == sit) & s["level"].isin(hp2_trials)]
            if h["level"].nunique() > 1:
                rows.append(effect(f"HP2 tool {sit}: trained above untrained ({strat}; log odds ratio)", ">0",
                                   logistic_trend(h.assign(trained=(h["level"] > 0).astype(int)), "trained")))
    both = df[df["strategy"].isin(strategies)]
    if both["strategy"].nunique() == 2:
        rows.append(effect("reactive and planning alike (paired by robot and group; difference of rates)", "~0",
                           paired_strategies(both), bound=EQUIVALENCE_BOUND))
    return holm(rows)
