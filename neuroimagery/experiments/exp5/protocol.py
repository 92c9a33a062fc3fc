"""Experiment 5: tool-use development in infant robots (thesis ch. 7, Fig. 7.5-7.6, 7.9-7.10).

Two simulations, each group 30 repetitions x 2 situations (tool behind toy = posture 1, tool far
from toy = posture 4), every individual tested both as a reactive and as a planning child:

* HP1: 2, 3, 4, 5, 6 IM detectors (ages 14-22 months; retrieve and touch always on, the others
  drawn at random per individual), 10 training trials.
* HP2: all six detectors, 0, 2, 4, 6, 8, 10 training trials (ages 14, 14, 16, 18, 20, 22 months).

Work unit ("task"): one repetition and one situation. Each detector set of the task's individuals
acquires its own skill library with exactly those detectors (Fig. 7.5); the individuals with the
same set (the HP2 groups, HP1's six-detector group) share it, their C1/C2/C3 training is replayed
from it, and each then runs Fig. 7.6. The individuals of one library share the (deterministic)
outcomes of skill sequences, so the physics of a given sequence runs once. Tasks run in parallel (joblib) and each leaves one small result
file in ``checkpoints/`` so an interrupted run resumes where it stopped (rerun with the same
``hydra.run.dir``).

``cfg.participants`` is not used: the individuals are ``repetitions x situations`` per group.
``train`` runs the whole developmental simulation (acquisition, training trials and the test of
every individual, since each individual's training is its own); ``evaluate`` aggregates, draws
and reports.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict
from pathlib import Path

import pandas as pd

from ...core.errors import UserInputError
from ...models.tool_use import N_POSTURES
from . import tasks as task_files
from .task import groups, imagined_routes, make_environment, routes_available, run_task  # noqa: F401 (public names)
from .config import ENGINE_KEYS, POOL_FREE_KEYS, SITUATIONS, THESIS, THESIS_TABLE_7_1, Exp5Config, dotted
from .summary import ROUTES, STRATEGIES, group_rates, library_columns, success_route, success_routes, summarise, table_7_1, thesis_claims



# ---------------------------------------------------------------------------------- helpers
def _exp(cfg) -> Exp5Config:
    return cfg.experiment


def repetitions(cfg) -> int:
    e = _exp(cfg)
    return e.quick.repetitions if cfg.preset == "quick" else e.repetitions


def trained_count(cfg) -> tuple[int, str]:
    """How many robots a run simulates (``cfg.participants`` is not used): repetitions x situations
    x groups, each tested as a reactive and as a planning child."""
    e = _exp(cfg)
    return repetitions(cfg) * len(e.situations) * len(groups(e)), "robots"


# the settings a task's skill library depends on (Fig. 7.5): the world and acquisition groups
# whole, and of the others what acts during acquisition (C2 -> HIP makes an event "not new"); the
# seed is compared apart. The other keys act only in Fig. 7.6.
LIBRARY_GROUPS = ("world", "acquisition")
LIBRARY_KEYS = ("brain.c2_eta",)
def tasks(cfg) -> list[dict]:
    e = _exp(cfg)
    return [dict(repetition=r, situations=[s], key=f"rep{r:03d}_{s}")
            for r in range(repetitions(cfg)) for s in e.situations]


# ---------------------------------------------------------------------------------- contract
def _task_path(run_or_dir, key: str) -> Path:
    root = run_or_dir.checkpoints if hasattr(run_or_dir, "checkpoints") else Path(run_or_dir) / "checkpoints"
    return Path(root) / f"exp5_{key}.pt"


def _stored(path: Path) -> dict | None:
    """The task file at ``path`` (None if absent); one that is not plain data or not a task file
    is refused (:func:`exp5_tasks.read_task`)."""
    return task_files.read_task(path)


def _same(stored: dict, e: Exp5Config, library: bool = False) -> bool:
    """Whether the stored settings are this run's: all but the engine's (:data:`ENGINE_KEYS`), or
    with ``library`` those a skill library depends on (:data:`LIBRARY_GROUPS`, :data:`LIBRARY_KEYS`)."""
    now, then = dotted(asdict(e)), dotted(stored)
    if library:
        keys = [k for k in now if k.split(".")[0] in LIBRARY_GROUPS or k in LIBRARY_KEYS]
    else:
        keys = [k for k in now if k not in ENGINE_KEYS]
    return all(then.get(k) == now[k] for k in keys)


def _finished(d: dict | None, e: Exp5Config, seed: int, library: bool = False) -> bool:
    """Whether the stored task ``d`` was computed with this seed and this configuration (or, with
    ``library``, its skill library with these acquisition settings)."""
    return d is not None and d.get("seed") == seed and _same(d["config"], e, library)


def _valid(path: Path, e: Exp5Config, seed: int) -> dict | None:
    """The finished task stored at ``path`` if it was computed with this configuration and seed."""
    d = _stored(path)
    return d if _finished(d, e, seed) else None


def _library_of(d: dict | None, e: Exp5Config, seed: int) -> dict | None:
    """The skill library of the stored task ``d`` if it was acquired with this task's acquisition
    settings and seed."""
    return d["libraries"] if _finished(d, e, seed, library=True) and "libraries" in d else None


def train(cfg, run) -> dict:
    """Run every task (skipping those already finished in this run directory); return the results."""
    from joblib import delayed
    from tqdm.auto import tqdm

    from ...core.workers import parallel

    e = _exp(cfg)
    task_files.remove_stale(run.checkpoints)  # left by workers stopped while writing
    todo, done, libraries = [], [], {}
    for t in tasks(cfg):
        d = _stored(_task_path(run, t["key"]))  # each checkpoint is read once
        if _finished(d, e, cfg.seed):
            done.append(d)
            continue
        todo.append(t)
        lib = _library_of(d, e, cfg.seed)
        if lib is None and e.engine.reuse_libraries:
            lib = _library_of(_stored(_task_path(e.engine.reuse_libraries, t["key"])), e, cfg.seed)
        libraries[t["key"]] = lib
    read_back = len(done)
    bar = tqdm(total=len(todo) + len(done), initial=len(done), desc="exp5 tasks", disable=not cfg.progress)
    if todo:
        jobs = (delayed(run_task)(e, cfg.seed, t, str(_task_path(run, t["key"])), libraries[t["key"]]) for t in todo)
        results = parallel(min(e.engine.n_jobs, len(todo)), return_as="generator_unordered")(jobs)
        try:
            for res in results:
                done.append(res)
                bar.update(1)
                run.logger.scalar("train/task_s", res["timing"]["task_s"], len(done))
        except BaseException:  # an interrupt (SIGINT, SIGTERM) or a failed task: finished tasks stay on disk
            with warnings.catch_warnings():  # joblib's note on the tasks it cancels
                warnings.simplefilter("ignore", UserWarning)
                results.close()  # joblib kills the workers still running (loky: terminate(kill_workers=True))
            task_files.remove_stale(run.checkpoints)
            raise
    bar.close()
    done.sort(key=lambda d: d["task"]["key"])
    run.save_checkpoint("exp5_index", {"keys": [d["task"]["key"] for d in done], "seed": cfg.seed})
    return {"results": done, "read_back": read_back,
            "libraries_reused": sum(v is not None for v in libraries.values())}


def load(cfg, checkpoint_dir) -> dict:
    e = _exp(cfg)
    out = []
    for t in tasks(cfg):
        d = _valid(_task_path(checkpoint_dir, t["key"]), e, cfg.seed)
        if d is None:
            raise UserInputError(f"checkpoint: {checkpoint_dir} has no finished task {t['key']} for this configuration")
        out.append(d)
    return {"results": out, "read_back": len(out)}


def evaluate(cfg, run, trained) -> dict:
    """individuals.csv, summary (docs/results.md, Experiment 5), figures and TensorBoard scalars."""
    from . import figures as figs

    e = _exp(cfg)
    results = trained["results"]
    df = pd.DataFrame([row for d in results for row in d["rows"]])
    df.insert(0, "individual", df["library"] + "_" + df["situation"])
    df = library_columns(df, results)
    last = [c for c in ("train_successes", "train_q") if c in df]  # the newest columns stay last
    df = df[[c for c in df.columns if c not in last] + last]
    run.write_csv("individuals.csv", df)
    rates = summarise(df, e)
    grp_rows, checks, routes = rates["groups"], rates["checks"], rates["routes"]
    timing = [d["timing"] for d in results]
    summary = {
        "experiment": "exp5",
        "groups": grp_rows,
        "table_7_1": table_7_1(results),
        "targets": {
            "hp1/behind": {str(k): v for k, v in THESIS["hp1"]["behind"].items()},
            "hp1/far": {str(k): v for k, v in THESIS["hp1"]["far"].items()},
            "hp2/behind": {str(k): v for k, v in THESIS["hp2"]["behind"].items()},
            "hp2/far": {str(k): v for k, v in THESIS["hp2"]["far"].items()},
            "hp1_far_spearman_min": 0.8,
        },
        "checks": checks,
        "routes": routes,
        "mechanism": rates["mechanism"],
        "repetitions": repetitions(cfg),
        # one individual = one robot of one group (repetition x situation), tested as both strategies
        "individuals": int(len(df) // len(STRATEGIES)),
        "environment": e.world.environment,
        "cost": {"tasks": len(results), "tasks_read_back": int(trained.get("read_back", 0)),
                 "libraries_reused": int(sum(bool(t.get("library_reused")) for t in timing)), "task_s_total": round(sum(t["task_s"] for t in timing), 2),
                 "task_cpu_s_total": (round(sum(t["cpu_s"] for t in timing), 2)
                                      if all("cpu_s" in t for t in timing) else None),
                 "acquisition_s_total": round(sum(t["acquisition_s"] for t in timing), 2),
                 "explore_rollouts": int(sum(t["explore_rollouts"] for t in timing)),
                 "learn_rollouts": int(sum(t["learn_rollouts"] for t in timing)),
                 "rollouts": int(sum(t.get("rollouts", 0) for t in timing)),
                 "renders": int(sum(t.get("renders", 0) for t in timing)),
                 "rollout_s": round(sum(t.get("rollout_s", 0.0) for t in timing), 2),
                 "render_s": round(sum(t.get("render_s", 0.0) for t in timing), 2)},
    }
    summary["claims"] = rates["claims"]
    summary["effects"] = rates["effects"]
    for i, r in enumerate(grp_rows):
        run.logger.scalar(f"success/{r['hypothesis']}/{r['situation']}/{r['strategy']}", r["success_rate"], r["level"])
    figs.draw_all(cfg, run, df, summary, results, situation_views(e) if e.world.environment == "robot" else None)
    return summary


def situation_views(e: Exp5Config) -> dict:
    """The four initial situations as the robot sees them, for the figures: ``eye`` the eye's
    images (None for a world without them) and ``pc`` the colour-filtered PC maps."""
    env = make_environment(e)
    try:
        starts = [env.start(p) for p in range(1, N_POSTURES + 1)]
        return {"eye": [env.eye_image(s) for s in starts] if hasattr(env, "eye_image") else None,
                "pc": [env.perceive(s) for s in starts]}
    finally:
        env.close()


def report(cfg, run, summary) -> None:
    from .report import write_report

    write_report(cfg, run, summary)


def pool_runs(run_dirs: list) -> tuple:
    """The pooling hook of :mod:`neuroimagery.app.pool`: the pooled summary, individuals and report of
    finished runs (:func:`neuroimagery.experiments.exp5.pool.pool_runs`)."""
    from . import pool as exp5_pool

    return exp5_pool.pool_runs(run_dirs)


__all__ = ["Exp5Config", "train", "load", "evaluate", "report", "run_task", "groups", "tasks",
           "thesis_claims", "success_route", "success_routes", "summarise", "group_rates", "routes_available", "imagined_routes"]
