"""Experiment 5 over several runs: group rates and must-show claims of the pooled individuals.

With 30 robots per group a success rate has a standard error of about 8 points, so a claim that
compares single groups can hold on one seed and fail on the next. Runs of the same configuration
with different seeds (``evaluate.py -m experiment=exp5 seed=0,1,2``) are pooled here: their
``individuals.csv`` rows are put together and judged with the same functions as one run
(:func:`neuroimagery.experiments.exp5.protocol.summarise`)::

    python -m neuroimagery.app.pool RUN_DIR RUN_DIR ... [--out DIR]

prints the pooled table and claims (a Hydra sweep directory stands for its numbered runs); ``--out`` also writes
``individuals.csv`` (with a ``run`` column), ``summary.json`` and ``report.md`` into DIR. The
command first checks the runs' manifests (:mod:`neuroimagery.app.pool`). The runs must agree on every experiment
setting except the engine's (``engine.n_jobs``, ``engine.reuse_libraries``,
``engine.filmstrip_repetition``) and the number of repetitions, and must have distinct seeds. A run whose ``individuals.csv`` does not hold
the rows its ``summary.json`` counts (cut short, header only, not a CSV file) is refused.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from ...analysis.report import Report
from ...analysis.robots import ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE
from ...analysis.tables import read_whole_csv
from ...core.errors import UserInputError
from .config import POOL_FREE_KEYS, Exp5Config, dotted, from_dict
from .report import group_table
from .summary import STRATEGIES, group_rates, summarise


def read_yaml(path: Path) -> dict:
    """A run's saved configuration as plain data; nothing in it is run (a safe YAML loader, no
    Python tags) and every way it can be unreadable is one ``UserInputError`` naming the file."""
    import yaml
    from omegaconf.errors import OmegaConfBaseException

    try:
        raw = OmegaConf.to_container(OmegaConf.load(path), resolve=True)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        what = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise UserInputError(f"{path}: not a configuration this package wrote: {what}{where}") from None
    except OmegaConfBaseException as err:  # an unknown resolver, a broken interpolation
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise UserInputError(f"{path}: cannot be resolved: {first[:200]}") from None
    except (OSError, UnicodeDecodeError, ValueError, TypeError) as err:
        raise UserInputError(f"{path}: cannot be read ({getattr(err, 'strerror', None) or err})") from None
    if not isinstance(raw, dict):
        raise UserInputError(f"{path}: not a mapping (not a configuration this package wrote)")
    return raw


def read_config(run_dir: str | Path) -> tuple[Exp5Config, int]:
    """The experiment settings and seed of one finished Exp. 5 run directory."""
    d = Path(run_dir)
    if not d.is_dir():
        raise UserInputError(f"{d}: no such run directory")
    cfg_path, csv_path = d / ".hydra" / "config.yaml", d / "individuals.csv"
    for path in (cfg_path, csv_path, d / "summary.json"):
        if not path.is_file():
            raise UserInputError(f"{d}: no {path.relative_to(d)} (not a finished Exp. 5 run directory)")
    raw = read_yaml(cfg_path)
    if not isinstance(raw.get("experiment") or {}, dict):
        raise UserInputError(f"{cfg_path}: 'experiment' is not a mapping (not a config this package wrote)")
    exp = dict(raw.get("experiment") or {})
    if exp.get("name") != "exp5":
        raise UserInputError(f"{d}: experiment {exp.get('name')!r}, not exp5")
    known = {f.name for f in dataclasses.fields(Exp5Config)}
    unknown = sorted(set(exp) - known)
    if unknown:
        raise UserInputError(f"{cfg_path}: unknown experiment keys {', '.join(unknown)}")
    exp.setdefault("engine", {})["reuse_libraries"] = ""  # an engine setting; the directory it named may be gone
    try:
        e = from_dict(exp)
    except TypeError as err:  # a key unknown inside a group
        raise UserInputError(f"{cfg_path}: unknown experiment key ({err})") from None
    except ValueError as err:
        raise UserInputError(f"{cfg_path}: {err}") from None
    try:
        return e, int(raw.get("seed", 0))
    except (TypeError, ValueError):
        raise UserInputError(f"{cfg_path}: seed {raw.get('seed')!r} is not an integer") from None


GROUP = ["hypothesis", "level", "situation", "strategy"]
NUMERIC = ("level", "age_months", "success", "n_skills")


def read_rows(csv_path: Path) -> pd.DataFrame:
    """The rows of one run's ``individuals.csv``, refused unless the file is whole: complete lines,
    the columns pooling needs, at least one row, no empty group key or test result."""
    try:
        return read_whole_csv(csv_path, sorted({*GROUP, *NUMERIC, "test_actions"}), NUMERIC, [*GROUP, *NUMERIC])
    except FileNotFoundError:
        raise UserInputError(f"{csv_path}: no such file") from None


def check_rows(df: pd.DataFrame, csv_path: Path, summary_path: Path) -> None:
    """Refuse rows that are not the ones ``summary.json`` was computed from: the number of rows of
    every group and its success rate must be the summary's."""
    try:
        groups = json.loads(summary_path.read_text())["groups"]
        stated = {(g["hypothesis"], int(g["level"]), g["situation"], g["strategy"]): (int(g["n"]), g["success_rate"])
                  for g in groups}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise UserInputError(f"{summary_path}: cannot read its groups ({type(err).__name__}: {err})") from None
    total = sum(n for n, _ in stated.values())
    if len(df) != total:
        raise UserInputError(f"{csv_path}: {len(df)} rows, but {summary_path.name} counts {total} "
                             "(cut short, or not this run's rows)")
    have = {(h, int(lv), si, st): (len(g), round(float(g["success"].mean()), 4))
            for (h, lv, si, st), g in df.groupby(GROUP, sort=False)}
    for key in sorted(set(stated) | set(have), key=str):
        if have.get(key) != stated.get(key):
            (n, rate), (n0, rate0) = have.get(key, (0, None)), stated.get(key, (0, None))
            raise UserInputError(f"{csv_path}: group {' '.join(map(str, key))} has {n} rows, success rate {rate}; "
                                 f"{summary_path.name} states {n0}, {rate0}")


def read_run(run_dir: str | Path) -> tuple[Exp5Config, int, pd.DataFrame]:
    """The experiment settings, seed and individuals of one finished Exp. 5 run directory."""
    e, seed = read_config(run_dir)
    csv_path = Path(run_dir) / "individuals.csv"
    df = read_rows(csv_path)
    check_rows(df, csv_path, Path(run_dir) / "summary.json")
    return e, seed, df


def expand(dirs: list[str | Path]) -> list[Path]:
    """Run directories, with a Hydra sweep directory (``-m``: numbered subdirectories, each a run)
    replaced by its runs in job order."""
    out = []
    for d in map(Path, dirs):
        if (d / ".hydra" / "config.yaml").is_file() or not d.is_dir():
            out.append(d)
            continue
        jobs = [c for c in d.iterdir() if (c / ".hydra" / "config.yaml").is_file()]
        jobs.sort(key=lambda c: (not c.name.isdigit(), int(c.name) if c.name.isdigit() else 0, c.name))
        out.extend(jobs or [d])
    return out


def pool(run_dirs: list[str | Path]) -> tuple[dict, pd.DataFrame]:
    """Pooled summary (``groups``, ``checks``, ``routes``, ``claims`` as in one run's summary.json,
    plus ``runs``: each run's seed, individuals and claims) and the pooled individuals.
    A Hydra sweep directory stands for its runs (:func:`expand`)."""
    run_dirs = expand(run_dirs)
    if len(run_dirs) < 1:
        raise UserInputError("pool: give at least one run directory")
    runs = [(str(d), *read_run(d)) for d in run_dirs]
    d0, e0, _, _ = runs[0]
    ref = dotted(dataclasses.asdict(e0))
    seen: dict[int, str] = {}
    for d, e, seed, _ in runs:
        now = dotted(dataclasses.asdict(e))
        diff = [k for k in ref if k not in POOL_FREE_KEYS and now.get(k) != ref[k]]
        if diff:
            k = diff[0]
            raise UserInputError(f"pool: experiment.{k} is {now.get(k)!r} in {d} but {ref[k]!r} in {d0}; "
                                 "pool runs of one configuration only")
        if seed in seen:
            raise UserInputError(f"pool: {d} and {seen[seed]} both have seed {seed} (the same robots twice)")
        seen[seed] = d
    df = pd.concat([df.assign(run=d) for d, _, _, df in runs], ignore_index=True)
    out = summarise(df, e0)
    out = {"experiment": "exp5", "pooled": True, **out, "runs": []}
    for d, e, seed, rdf in runs:
        s = summarise(rdf, e)
        out["runs"].append(dict(run=d, seed=seed, individuals=int(len(rdf) // len(STRATEGIES)),
                                claims_holding=int(sum(c["holds"] for c in s["claims"])), claims=len(s["claims"]),
                                groups=s["groups"]))
    return out, df


def report(summary: dict, e: Exp5Config) -> Report:
    """The pooled rates beside each run's and the thesis's, and the claims judged on the pool."""
    runs = summary["runs"]
    rep = Report("Experiment 5 pooled over runs")
    rep.p(f"{len(runs)} runs (seeds {', '.join(str(r['seed']) for r in runs)}), "
          f"{sum(r['individuals'] for r in runs)} robots, each tested as a reactive and as a planning child. "
          "Each cell: the pooled rate, then each run's in brackets (run order as listed below).")
    pooled, per = group_rates(summary["groups"]), [group_rates(r["groups"]) for r in runs]

    def cell(h, lv, sit, strat):
        key = (h, lv, sit, strat)
        if key not in pooled:
            return "-"
        each = ", ".join("-" if key not in p else f"{100 * p[key]:.0f}" for p in per)
        return f"{100 * pooled[key]:.0f} % ({each})"

    for h, xl in (("hp1", "IM detectors"), ("hp2", "training trials")):
        rep.h(f"{h.upper()}: success rate by {xl}")
        rep.table(*group_table(e, h, cell))
    claims = summary["claims"]
    n = min(g["n"] for g in summary["groups"])
    rep.h("Must-show claims on the pooled individuals")
    rep.p(f"{sum(c['holds'] for c in claims)} of {len(claims)} hold on the pool ({n} robots per group or more). "
          "Per run: " + "; ".join(f"seed {r['seed']}: {r['claims_holding']} of {r['claims']}" for r in runs) + ".")
    rep.table(["claim", "pooled", "holds"], [[c["claim"], c["value"], "yes" if c["holds"] else "**no**"] for c in claims])
    if summary.get("effects"):
        rep.h("Effects over the pooled robots, the robot as the unit")
        rep.effects(summary["effects"], ROBOT_EFFECTS_INTRO, ROBOT_EQUIVALENCE)
    mech = summary.get("mechanism") or {}
    if mech:
        rep.h("The mechanism of the tool-far test, pooled")
        rep.table(["check", "count", "share"],
                  [[k, ", ".join(f"{n} {v}" for n, v in m.items() if n != "share"),
                    "n/a" if m["share"] is None else f"{100 * m['share']:.0f} %"] for k, m in mech.items()])
    rep.h("Runs")
    rep.bullets([f"`{r['run']}`: seed {r['seed']}, {r['individuals']} robots" for r in runs])
    return rep


def pool_runs(run_dirs: list[str | Path]) -> tuple[dict, pd.DataFrame, Report]:
    """:func:`pool` and its :func:`report` (on the first run's settings): Experiment 5's pooling hook
    (:func:`neuroimagery.experiments.exp5.protocol.pool_runs`)."""
    summary, df = pool(run_dirs)
    return summary, df, report(summary, read_config(expand(run_dirs)[0])[0])
