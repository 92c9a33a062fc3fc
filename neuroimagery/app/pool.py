"""Runs of one configuration with different seeds, pooled: ``python -m neuroimagery.app.pool``.

::

    python -m neuroimagery.app.pool RUN_DIR RUN_DIR ... [--out OUT]
    python -m neuroimagery.app.pool SWEEP_DIR --out OUT      # the runs of evaluate.py -m ... seed=0,1,2

A Hydra sweep directory stands for the runs in its subdirectories (those holding a
``manifest.json``, in job order). The runs must be finished runs of one experiment whose manifests
have the same ``settings`` except ``seed`` (each differing key is named), with distinct seeds; each
``trials.csv`` must hold the rows its ``summary.json`` was computed from (row counts and rates per
test). Every refusal is one ``error:`` line naming the file or the key.

Experiments 1-4 and the demo: OUT gets ``trials.csv`` (every run's rows, with ``run`` and ``seed``
columns added), ``summary.json`` (per test the figures of one run's summary computed on the rows of
all runs, with ``per_seed`` values and their ``across_seeds`` mean, SD, min and max) and
``report.md`` (a table per test: each seed, the mean and SD across seeds, the pooled value and the
thesis's target). An experiment may pool its runs itself (the pooling hook of
:class:`neuroimagery.core.experiment.Experiment`): ``pool_runs(run_dirs) -> (summary, rows,
report)``, with ``pool_free_keys`` (the experiment settings that may differ between the runs
besides the seed). Experiment 5 does (rates, routes and claims on all robots, in ``individuals.csv``:
:mod:`neuroimagery.experiments.exp5.pool`).
"""
from __future__ import annotations

import json
import math
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..core import console, manifest as mf
from ..analysis.report import Report
from ..core.arguments import ToolParser, path
from ..analysis.summary import TRIAL_COLUMNS, summarise_test
from ..analysis.tables import read_whole_csv
from ..config import EXPERIMENTS, experiment
from ..core.checkpoints import read_json
from ..core.errors import UserInputError
from ..core.files import writable_folder, write_atomic

# per test: (key in summary.json, label in report.md, a rate shown in %?)
MEASURES = (("correct_rate", "correct", True), ("error_rate", "error", True),
            ("rotation_success_rate", "rotation success", True), ("error_rate_same", "NO to same pairs", True),
            ("error_rate_different", "YES to mirror pairs", True), ("rt_mean", "RT mean", False))
NUMERIC = ("participant", "disparity", "rt")
TITLES = {"demo": "Demo", **{f"exp{k}": f"Experiment {k}" for k in range(1, 6)}}


@dataclass
class Run:
    """A finished run directory: its manifest and summary."""

    dir: Path
    manifest: dict
    summary: dict

    experiment = property(lambda self: self.manifest.get("experiment"))
    seed = property(lambda self: self.manifest.get("seed"))


# ------------------------------------------------------------------------------ finding runs
def find_runs(dirs: list[str | Path]) -> list[Path]:
    """Run directories (holding ``manifest.json``), a sweep directory replaced by its runs in job order."""
    out = []
    for d in map(Path, dirs):
        if not d.is_dir():
            raise UserInputError(f"{d}: no such run directory")
        if (d / "manifest.json").is_file():
            out.append(d)
            continue
        if (d / ".hydra").is_dir():  # a run directory without a manifest: written by 0.1.0
            mf.usable_run(d, "pool")
        jobs = [c for c in d.iterdir() if (c / "manifest.json").is_file() or (c / ".hydra").is_dir()]
        if not jobs:
            raise UserInputError(f"{d}: not a finished run directory nor a sweep directory holding runs "
                                 "(no manifest.json in it or in its subdirectories)")
        jobs.sort(key=lambda c: (not c.name.isdigit(), int(c.name) if c.name.isdigit() else 0, c.name))
        out.extend(jobs)
    if not out:
        raise UserInputError("pool: give at least one run directory")
    return out


def _json(path: Path, what: str) -> dict:
    if not path.exists():
        raise UserInputError(f"{path.parent}: no {path.name} ({what})")
    return read_json(path)


def read_run(d: Path) -> Run:
    """The manifest and summary of one run directory; refused unless the run is finished."""
    # the files' hashes are checked after the rows (read_trials, pool_trials): a changed table is
    # then named with what changed in it
    manifest = mf.usable_run(d, "pool", files=None)
    summary = _json(d / "summary.json", "not a finished run: it stopped, or is still running")
    return Run(d, manifest, summary)


def check_runs(runs: list[Run], free: tuple[str, ...] = ()) -> None:
    """One experiment, the same settings except ``seed`` (and ``free``), distinct seeds."""
    first = runs[0]
    for r in runs[1:]:
        if r.experiment != first.experiment:
            raise UserInputError(f"pool: {r.dir} is a run of {r.experiment}, {first.dir} of {first.experiment}; "
                                 "pool runs of one experiment")
        a, b = first.manifest["settings"], r.manifest["settings"]
        diff = [f"{k} {a.get(k, '<absent>')!r} in {first.dir} but {b.get(k, '<absent>')!r} in {r.dir}"
                for k in sorted(set(a) | set(b)) if k != "seed" and k not in free and a.get(k) != b.get(k)]
        if diff:
            raise UserInputError(f"pool: runs with other settings: {'; '.join(diff)} (pool runs that differ only "
                                 "in seed)")
    seen: dict = {}
    for r in runs:
        if r.seed in seen:
            raise UserInputError(f"pool: {r.dir} and {seen[r.seed]} both have seed {r.seed} (the same participants "
                                 "twice)")
        seen[r.seed] = r.dir
    versions = sorted({str(r.manifest.get("package")) for r in runs})
    if len(versions) > 1:
        console.note(f"pooling runs written by versions {', '.join(versions)}")


# ---------------------------------------------------------------------------- reading rows
def read_trials(run: Run) -> pd.DataFrame:
    """``trials.csv`` of a run, refused unless it is whole: complete lines, the public columns, at
    least one row, no empty field where a figure is computed from."""
    path = run.dir / "trials.csv"
    try:
        df = read_whole_csv(path, TRIAL_COLUMNS, NUMERIC,
                            ["participant", "test", "condition", "disparity", "same", "correct", "rotated_ok", "rt"])
    except FileNotFoundError:
        raise UserInputError(f"{run.dir}: no trials.csv (not a finished run of {run.experiment})") from None
    for col in ("same", "correct", "rotated_ok"):
        if not pd.api.types.is_bool_dtype(df[col]):
            raise UserInputError(f"{path}: column {col} is not True/False")
    return df


def _close(a, b, rate: bool) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return abs(float(a) - float(b)) <= (1e-4 if rate else max(2e-3, 1e-6 * abs(float(b))))


def figures_of(df: pd.DataFrame, run: Run) -> dict:
    """Per ``<test>/<condition>`` the figures of the rows, refused unless they are the ones the run's
    ``summary.json`` states (the tests, their trial counts and the :data:`MEASURES`)."""
    csv, name = run.dir / "trials.csv", "summary.json"
    stated = run.summary.get("tests")
    if not isinstance(stated, dict) or not stated:
        raise UserInputError(f"{run.dir / name}: no tests")
    have = {f"{t}/{c}": summarise_test(g) for (t, c), g in df.groupby(["test", "condition"], sort=False)}
    for key in sorted(set(have) | set(stated)):
        if key not in have:
            raise UserInputError(f"{csv}: no rows of test {key}, which {name} states (not this run's rows)")
        if key not in stated:
            raise UserInputError(f"{csv}: rows of test {key}, which {name} does not state (not this run's rows)")
        n, n0 = have[key]["n_trials"], stated[key].get("n_trials")
        if n != n0:
            raise UserInputError(f"{csv}: test {key} has {n} rows, but {name} counts {n0} (cut short, or not this "
                                 "run's rows)")
        for m, _, rate in MEASURES:
            if not _close(have[key].get(m), stated[key].get(m), rate):
                raise UserInputError(f"{csv}: test {key} {m} is {have[key].get(m)} from the rows, {stated[key].get(m)} "
                                     f"in {name} (not this run's rows)")
    return have


# ------------------------------------------------------------------------------ pooling
def _spread(values: list) -> dict:
    vals = [float(v) for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if not vals:
        return {"mean": None, "sd": None, "min": None, "max": None, "n": 0}
    sd = statistics.stdev(vals) if len(vals) > 1 else None
    return {"mean": round(statistics.fmean(vals), 4), "sd": None if sd is None else round(sd, 4),
            "min": round(min(vals), 4), "max": round(max(vals), 4), "n": len(vals)}


def pool_trials(runs: list[Run]) -> tuple[dict, pd.DataFrame]:
    """Pooled summary and rows of runs of Experiments 1-4 or the demo (checked with :func:`check_runs`)."""
    frames, per_run = [], []
    for r in runs:
        df = read_trials(r)
        per_run.append(figures_of(df, r))
        frames.append(df.assign(run=str(r.dir), seed=r.seed))
    rows = pd.concat(frames, ignore_index=True)
    tests = {}
    for (t, c), g in rows.groupby(["test", "condition"], sort=False):
        key = f"{t}/{c}"
        per_seed = {str(r.seed): {m: fig[key][m] for m, _, _ in MEASURES} for r, fig in zip(runs, per_run)}
        across = {m: _spread([p[m] for p in per_seed.values()]) for m, _, _ in MEASURES}
        tests[key] = {**summarise_test(g), "per_seed": per_seed, "across_seeds": across}
    targets = runs[0].summary.get("targets") or {}
    if any((r.summary.get("targets") or {}) != targets for r in runs[1:]):
        console.note(f"the runs state different thesis targets; the report shows those of {runs[0].dir}")
    counts = [int(f.participant.nunique()) for f in frames]
    for r in runs:
        mf.verify_files(r.dir, r.manifest, "pool")
    summary = {"experiment": runs[0].experiment, "pooled": True, "seeds": [r.seed for r in runs],
               "preset": runs[0].manifest["settings"].get("preset", "full"),
               "participants": sum(counts), "tests": tests, "targets": targets,
               "effects": pooled_effects(runs[0].experiment, rows),
               "runs": [{"run": str(r.dir), "seed": r.seed, "participants": n, "package": r.manifest.get("package")}
                        for r, n in zip(runs, counts)]}
    return summary, rows


def pooled_effects(name: str, rows: pd.DataFrame) -> list[dict]:
    """The experiment's effects (its ``effects(trials)``) over the participants of all runs, each
    participant of each seed one unit (participant ids repeat across seeds, so the unit is the
    pair); an empty list for an experiment that states none."""
    fn = experiment(name).effects
    if fn is None:
        return []
    unit = rows["seed"].astype(str) + ":" + rows["participant"].astype(str)
    return fn(rows.assign(participant=pd.factorize(unit)[0]))


def _cell(v, rate: bool, spread: bool = False) -> str:
    if v is None:
        return "-"
    if rate:
        return f"{100 * v:.1f} pts" if spread else f"{100 * v:.1f} %"
    return f"{v:.3g}" if isinstance(v, float) else str(v)


def report_trials(summary: dict) -> Report:
    """A table per test: each seed's value, mean and SD across seeds, the pooled value, the thesis's."""
    runs, targets = summary["runs"], summary["targets"]
    seeds = [str(r["seed"]) for r in runs]
    rep = Report(f"{TITLES.get(summary['experiment'], summary['experiment'])} pooled over {len(runs)} runs")
    rep.p(f"Preset `{summary.get('preset', 'full')}`. {len(runs)} runs of the same settings (seeds {', '.join(seeds)}), "
          f"{summary['participants']} participants in all. Per test: each seed's value, their mean and standard deviation across seeds (SD: none with one "
          "seed), the value on all trials of all runs, and the thesis's figure where the summary of a run states "
          "one. RT in the experiment's own unit.")
    shown = set()
    for key, t in summary["tests"].items():
        rep.h(f"{key} ({t['n_trials']} trials)")
        rows = []
        for m, label, rate in MEASURES:
            target = (targets.get(key) or {}).get(m)
            if target is not None:
                shown.add((key, m))
            a = t["across_seeds"][m]
            rows.append([label, *(_cell(t["per_seed"][s][m], rate) for s in seeds), _cell(a["mean"], rate),
                         _cell(a["sd"], rate, spread=True), _cell(t[m], rate), _cell(target, rate)])
        rep.table(["measure", *(f"seed {s}" for s in seeds), "mean", "SD", "pooled", "thesis"], rows)
    if summary.get("effects"):
        rep.h(f"Effects over all {summary['participants']} participants, the participant as the unit")
        rep.effects(summary["effects"])
    rest = [f"{k}: {m} {_cell(v, 'rate' in m or 'success' in m)}" for k, d in targets.items() if isinstance(d, dict)
            for m, v in d.items() if (k, m) not in shown and isinstance(v, (int, float))]
    if rest:
        rep.h("Other figures of the thesis (not pooled here)")
        rep.bullets(rest)
    rep.h("Runs")
    rep.bullets([f"`{r['run']}`: seed {r['seed']}, {r['participants']} participants, version {r['package']}"
                 for r in runs])
    return rep


def _hook(name: str):
    """The experiment if it pools its runs itself (``pool_runs``), else None."""
    e = experiment(name) if name in EXPERIMENTS else None
    return e if e is not None and e.pool_runs is not None else None


def pool(dirs: list[str | Path]) -> tuple[dict, pd.DataFrame, Report]:
    """Pooled summary, rows and report of the runs in ``dirs`` (run or sweep directories)."""
    runs = [read_run(d) for d in find_runs(dirs)]
    hook = _hook(runs[0].experiment)
    if hook is not None:
        check_runs(runs, free=tuple(f"experiment.{k}" for k in hook.pool_free_keys))
        summary, df, rep = hook.pool_runs([r.dir for r in runs])
        for r in runs:
            mf.verify_files(r.dir, r.manifest, "pool")
        return summary, df, rep
    check_runs(runs)
    summary, df = pool_trials(runs)
    return summary, df, report_trials(summary)


# ------------------------------------------------------------------------------- writing
def _write(path: Path, text: str | None = None, frame: pd.DataFrame | None = None, float_format=None) -> None:
    def put(tmp: Path) -> None:
        if frame is not None:
            frame.to_csv(tmp, index=False, float_format=float_format)
        else:
            tmp.write_text(text)

    try:
        write_atomic(path, put)
    except OSError as err:
        raise UserInputError(f"cannot write {path}: {err.strerror or err}") from None


def check_out(out: str | Path) -> Path:
    """``--out`` before any pooling: not a run directory, a folder that can be made and written."""
    return writable_folder(out, refuse_run_dir=True)


def write(out: str | Path, summary: dict, df: pd.DataFrame, rep: Report) -> Path:
    """Write the pooled table (``trials.csv``, or the experiment's ``pool_rows``), ``summary.json`` and
    ``report.md`` into ``out``, each atomically; returns the report's path."""
    out = check_out(out)
    hook = _hook(summary["experiment"])
    if hook is not None:
        _write(out / hook.pool_rows, frame=df)
    else:  # as a run writes its trials.csv
        _write(out / "trials.csv", frame=df, float_format="%.6g")
    _write(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    _write(out / "report.md", rep.text())
    return out / "report.md"


def main(argv: list[str] | None = None, prog: str = "python -m neuroimagery.app.pool") -> None:
    ap = ToolParser(prog=prog, description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=path, help="finished run directories of one experiment and settings (distinct seeds), "
                    "or a Hydra sweep directory holding them")
    ap.add_argument("--out", type=path, help="write the pooled table, summary.json and report.md here")
    args = ap.parse_args(argv)
    if args.out is not None:
        check_out(args.out)
    summary, df, rep = pool(args.runs)
    sys.stdout.write(rep.text())
    if args.out is not None:
        console.info(f"pooled report: {write(args.out, summary, df, rep)}")


if __name__ == "__main__":
    from .cli import friendly_errors

    friendly_errors(main)()
