"""Experiment 5: tool-use development in infant robots (thesis ch. 7, Fig. 7.5-7.6, 7.9-7.10).

Two simulations, each group 30 repetitions x 2 situations (tool behind toy = posture 1, tool far
from toy = posture 4), every individual tested both as a reactive and as a planning child:

* HP1: 2, 3, 4, 5, 6 IM detectors (ages 14-22 months; retrieve and touch always on, the others
  drawn at random per individual), 10 training trials.
* HP2: all six detectors, 0, 2, 4, 6, 8, 10 training trials (ages 14, 14, 16, 18, 20, 22 months).

Work unit ("task"): one repetition and one situation (or both, with
``engine.share_library_across_situations``). Each detector set of the task's individuals
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

import copy
import importlib
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from ..errors import UserInputError
from ..moved_keys import fill_added
from ..models.tool_use import EVENTS, N_POSTURES, Library, Outcomes, ToolUseBrain, acquire_skills, build_brain, run_trial
from ..nn.seeding import participant_seed
from . import exp5_tasks as task_files
from .exp5_checks import check_inputs  # noqa: F401  (checks before work: neuroimagery.validation)
from .exp5_config import (ENGINE_KEYS, MOVED_KEYS, POOL_FREE_KEYS, SITUATIONS, THESIS,  # noqa: F401 (public names)
                          THESIS_TABLE_7_1, Exp5Config, dotted, nest)
from .exp5_summary import (ROUTES, STRATEGIES, group_rates, library_columns, success_route,  # noqa: F401
                           success_routes, summarise, table_7_1, thesis_claims)


CONFIG = Exp5Config

# what validation and the manifests need to know (neuroimagery.validation, neuroimagery.manifest)
INPUTS = ()  # the robot's eye is part of the world (neuroimagery.robot), not the vision group
CHECKPOINTS = ("exp5_index",)
POOL_ROWS = "individuals.csv"  # the pooled rows (neuroimagery.pool, with POOL_FREE_KEYS and pool_runs)
RUNTIME_KEYS = ("engine.n_jobs", "engine.reuse_libraries", "engine.filmstrip_repetition")  # speed, reuse, who is filmed
TEST_KEYS = ()


def ineffective_keys(cfg) -> dict[str, str]:
    out = {"participants": "exp5 simulates experiment.repetitions robots per group and situation"}
    if cfg.preset == "quick":
        out["experiment.repetitions"] = "preset=quick runs experiment.quick.repetitions"
    return out


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
# whole, and of the others what acts during acquisition (C2 -> HIP makes an event "not new"; one
# library for both situations); the seed is compared apart. The other keys act only in Fig. 7.6.
LIBRARY_GROUPS = ("world", "acquisition")
LIBRARY_KEYS = ("brain.c2_eta", "engine.share_library_across_situations")
_WORKER_ENV: dict[tuple, object] = {}  # one world per worker process, reused by its tasks


def _task_environment(e: Exp5Config):
    """This process's world for ``e`` (built once: loading the robot takes seconds), emptied of
    the previous task's image cache and timings so each task's numbers are its own."""
    key = tuple(asdict(e.world).items())
    env = _WORKER_ENV.get(key)
    if env is None:
        for old in _WORKER_ENV.values():
            if hasattr(old, "close"):
                old.close()
        _WORKER_ENV.clear()
        env = _WORKER_ENV[key] = make_environment(e)
    if hasattr(env, "_images"):
        env._images.clear()
    if hasattr(env, "timing"):
        env.timing = {k: type(v)(0) for k, v in env.timing.items()}
    return env


def make_environment(e: Exp5Config):
    """The world the robots live in: the pybullet ToolWorld, or ``module:Class`` (tests' stand-ins)."""
    w = e.world
    if w.environment == "robot":
        from ..robot.environment import ToolWorldEnvironment

        return ToolWorldEnvironment(w.world_config(), **w.env_kwargs())
    mod, _, cls = w.environment.partition(":")
    try:
        return getattr(importlib.import_module(mod), cls)()
    except (ImportError, AttributeError) as err:
        raise UserInputError(f"experiment.world.environment: cannot load {w.environment!r} ({err})") from None


def groups(e: Exp5Config) -> list[dict]:
    """Every group: hypothesis, level, age, training trials and number of detectors."""
    out = [dict(hypothesis="hp1", level=k, age_months=a, trials=e.hp1_training_trials, detectors=k)
           for k, a in zip(e.hp1_levels, e.hp1_ages)]
    out += [dict(hypothesis="hp2", level=t, age_months=a, trials=t, detectors=len(EVENTS))
            for t, a in zip(e.hp2_trials, e.hp2_ages)]
    return out


def tasks(cfg) -> list[dict]:
    e = _exp(cfg)
    sits = list(e.situations)
    out = []
    for r in range(repetitions(cfg)):
        if e.engine.share_library_across_situations:
            out.append(dict(repetition=r, situations=sits, key=f"rep{r:03d}"))
        else:
            out += [dict(repetition=r, situations=[s], key=f"rep{r:03d}_{s}") for s in sits]
    return out


def _gen(seed: int, *ids: int) -> torch.Generator:
    key = 0
    for i in ids:
        key = key * 1009 + int(i) + 1
    g = torch.Generator()
    g.manual_seed(participant_seed(seed, key % (2**31)))
    return g


def detectors_for(e: Exp5Config, n: int, g: torch.Generator) -> list[str]:
    """The ``n`` enabled IM detectors: the base ones plus a random draw of the rest."""
    rest = [x for x in EVENTS if x not in e.base_detectors]
    extra = [rest[i] for i in torch.randperm(len(rest), generator=g)[: n - len(e.base_detectors)].tolist()]
    return [x for x in EVENTS if x in e.base_detectors or x in extra]


def _pack(img: torch.Tensor) -> torch.Tensor:
    return (img.clamp(0, 1) * 255).round().to(torch.uint8)


def _small_maps(maps: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Weight maps at half resolution in float16, small enough to keep in the filmed task's checkpoint."""
    return {k: torch.nn.functional.avg_pool2d(v[None, None].float(), 2)[0, 0].half() for k, v in maps.items()}


def routes_available(outcomes: Outcomes, posture: int, names: Sequence[str]) -> tuple[int, int]:
    """What the world offers a robot with primitives ``names`` from ``posture``, whatever it learns:
    the number of single primitives that retrieve the toy, and of ordered pairs (a, b) where a alone
    does not and a then b does (individuals.csv ``routes_1``, ``routes_2``; rollouts are cached in
    ``outcomes`` and shared with the action sequencing)."""
    one = {a for a in names if outcomes.after(posture, (a,)).retrieved}
    two = sum(outcomes.after(posture, (a, b)).retrieved for a in names if a not in one for b in names)
    return len(one), int(two)


def imagined_routes(brain: ToolUseBrain, outcomes: Outcomes, posture: int, skills: Sequence) -> tuple[int, int, int]:
    """What a planning child's mental images offer from ``posture``: the number of primitives that
    C3, run backwards, imagines to bring the toy into reach, of ordered pairs a, b (a alone not
    imagined to) whose second mental image shows it in reach, and of these imagined routes how many
    also bring the toy in for real (individuals.csv ``imagined_1``, ``imagined_2``,
    ``imagined_true``; the real check reuses the rollouts of :func:`routes_available`)."""
    env = outcomes.env
    x0 = outcomes.image(posture, ())
    first = {s.name: brain.imagine(x0, s.unit) for s in skills}
    one = [a for a, im in first.items() if env.reward(im) > 0]
    two = [(a, s.name) for a, im in first.items() if a not in one for s in skills
           if env.reward(brain.imagine(im, s.unit)) > 0]

    def real(moves):
        return outcomes.after(posture, moves[:1]).retrieved or outcomes.after(posture, moves).retrieved

    true = sum(real((a,)) for a in one) + sum(real(ab) for ab in two)
    return len(one), len(two), int(true)


# ---------------------------------------------------------------------------------- one task
def run_task(e: Exp5Config, seed: int, task: dict, path: str | None = None, library: dict | None = None) -> dict:
    """Acquire one library (or take ``library``, a stored one acquired with the same settings),
    then simulate every individual built on it (all groups, strategies)."""
    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()
    env = _task_environment(e)
    acq = e.acquisition
    r = task["repetition"]
    sit_ids = [list(SITUATIONS).index(s) for s in task["situations"]]

    fresh: list[ToolUseBrain] = []

    def new_brain() -> ToolUseBrain:
        # every brain of a run starts from the same seed, so a task draws C3's initial weights
        # (tens of MB) once and hands each new brain a copy of that untouched brain
        if not fresh:
            fresh.append(ToolUseBrain.from_params(env.image_shape, e.brain, n_dmps=acq.n_dmps, seed=seed))
        return copy.deepcopy(fresh[0])

    # each robot acquires its library with its own enabled detectors (Fig. 7.5; docs/contracts.md
    # W11): one library per detector set, shared only by the robots with the same set (the HP2
    # groups and HP1's six-detector group)
    stored = {k: Library.from_state(v) for k, v in (library or {}).items()}
    libs: dict[str, Library] = {}
    t_acq = 0.0

    def library_for(enabled: list[str]) -> Library:
        nonlocal t_acq
        name = "+".join(enabled)
        if name not in libs:
            t1 = time.perf_counter()
            mask = sum(1 << EVENTS.index(x) for x in enabled)
            libs[name] = stored[name] if name in stored else acquire_skills(
                env, enabled, acq, _gen(seed, 1, r, *sit_ids, mask), brain=new_brain())
            t_acq += time.perf_counter() - t1
        return libs[name]

    rows, film = [], None
    built: dict[tuple, ToolUseBrain] = {}
    outcomes_of: dict[tuple, Outcomes] = {}
    # per (situation, detectors): routes_1, routes_2 (the world) and imagined_1, imagined_2,
    # imagined_true (the mental images; C3 does not change in action sequencing)
    routes: dict[tuple, dict[str, int]] = {}
    for sit in task["situations"]:
        posture = SITUATIONS[sit]
        for gi, grp in enumerate(groups(e)):
            g_ind = _gen(seed, 2, r, list(SITUATIONS).index(sit), gi)
            enabled = detectors_for(e, grp["detectors"], g_ind)
            sub = library_for(enabled)
            key = tuple(enabled)
            if (sit, key) not in outcomes_of:  # rollouts of this library's skills, shared by its robots
                outcomes_of[(sit, key)] = Outcomes(env, {s.name: s for s in sub.skills}, env.perceive)
            outcomes = outcomes_of[(sit, key)]
            if key not in built:
                built[key] = build_brain(env, sub, acq, new_brain(), _gen(seed, 3, r), env.perceive, outcomes=outcomes)
            if (sit, key) not in routes:
                r1, r2 = routes_available(outcomes, posture, [s.name for s in sub.skills])
                i1, i2, i_true = imagined_routes(built[key], outcomes, posture, sub.skills)
                pulls = [s.name for s in sub.skills if s.event == "retrieve"]
                # the mechanism check of the tool-far test: does a learnt pull alone bring the toy in?
                # (-1: the robot has no pull)
                pull_alone = int(any(outcomes.after(posture, (a,)).retrieved for a in pulls)) if pulls else -1
                routes[(sit, key)] = dict(routes_1=r1, routes_2=r2, imagined_1=i1, imagined_2=i2, imagined_true=i_true,
                                          pull_alone=pull_alone)
            for strategy in STRATEGIES:
                # only C4 learns in Fig. 7.6: every individual starts from the built brain with a fresh C4
                brain = built[key]
                brain.reset_c4()
                train_ok, train_q = [], []
                start, units = outcomes.image(posture, ()), [s.unit for s in sub.skills]
                for _ in range(grp["trials"]):
                    rec = run_trial(brain, outcomes, sub.skills, posture, strategy, True, e.sequencing, g_ind)
                    train_ok.append(rec.success if strategy == "reactive" else rec.imagined_success)
                    # C4's learning curve: the largest action value of the robot's skills at the start
                    train_q.append(float(brain.q_values(start)[units].max()) if units else 0.0)
                filming = (film is None and r == e.engine.filmstrip_repetition and strategy == "planning")
                test = run_trial(brain, outcomes, sub.skills, posture, strategy, False, e.sequencing, g_ind,
                                 record_frames=filming)
                if filming and test.success and (sit == "far" or gi == len(groups(e)) - 1):
                    film = dict(situation=sit, hypothesis=grp["hypothesis"], level=grp["level"],
                                strategy=strategy, start=_pack(outcomes.image(posture, ())),
                                frames=[dict(action=f["action"], reward=f["reward"], real=_pack(f["real"]),
                                             imagined=_pack(f["imagined"])) for f in test.frames],
                                maps=_small_maps(brain.maps({s.name: s.unit for s in sub.skills})))
                rows.append(dict(
                    hypothesis=grp["hypothesis"], level=grp["level"], age_months=grp["age_months"],
                    situation=sit, strategy=strategy, repetition=r, library=task["key"],
                    training_trials=grp["trials"], n_detectors=len(enabled), detectors="+".join(enabled),
                    n_skills=len(sub.skills), skills="+".join(s.name for s in sub.skills),
                    train_success_rate=float(np.mean(train_ok)) if train_ok else float("nan"),
                    success=int(test.success), imagined_success=int(test.imagined_success),
                    test_actions=">".join(test.actions), test_attempts=len(test.actions), **routes[(sit, key)],
                    train_successes=">".join(str(int(ok)) for ok in train_ok),
                    train_q=">".join(f"{q:.6g}" for q in train_q)))
    fresh_libs = [v for k, v in libs.items() if k not in stored]
    timing = dict(task_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0, acquisition_s=t_acq,
                  explore_rollouts=sum(v.explore_rollouts for v in fresh_libs),
                  learn_rollouts=sum(v.learn_rollouts for v in fresh_libs), library_reused=library is not None,
                  libraries=len(libs))
    timing.update({k: v for k, v in getattr(env, "timing", {}).items()})
    six = "+".join(EVENTS)
    main_lib = libs.get(six) or next(iter(libs.values()), Library([], [[0] * len(EVENTS) for _ in range(4)]))
    # ``library``: the six-detector library (Table 7.1 from the robots' learning); ``libraries``:
    # every detector set's own library, by its detectors joined with '+'
    out = dict(task=task, rows=rows, library=main_lib.to_state(), libraries={k: v.to_state() for k, v in libs.items()},
               film=film, timing=timing, config=asdict(e), seed=seed)
    if path is not None:
        task_files.save(out, path)
    return out


# ---------------------------------------------------------------------------------- contract
def _task_path(run_or_dir, key: str) -> Path:
    root = run_or_dir.checkpoints if hasattr(run_or_dir, "checkpoints") else Path(run_or_dir) / "checkpoints"
    return Path(root) / f"exp5_{key}.pt"


def _stored(path: Path) -> dict | None:
    """The task file at ``path`` (None if absent); one that is not plain data or not a task file
    is refused (:func:`exp5_tasks.read_task`)."""
    d = task_files.read_task(path)
    if d is None:
        return None
    if "acquisition" not in d["config"]:  # the flat layout of earlier versions: its keys into their groups
        d["config"] = nest(d["config"])
    # written before a key existed: its value then (neuroimagery.moved_keys.ADDED)
    d["config"] = fill_added(d["config"], "exp5")
    return d


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

    from ..workers import parallel

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
    from . import exp5_figures as figs

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
    from .exp5_report import write_report

    write_report(cfg, run, summary)


def pool_runs(run_dirs: list) -> tuple:
    """The pooling hook of :mod:`neuroimagery.pool`: the pooled summary, individuals and report of
    finished runs (:func:`neuroimagery.experiments.exp5_pool.pool_runs`)."""
    from . import exp5_pool

    return exp5_pool.pool_runs(run_dirs)


__all__ = ["Exp5Config", "CONFIG", "train", "load", "evaluate", "report", "run_task", "groups", "tasks",
           "thesis_claims", "success_route", "success_routes", "summarise", "group_rates", "routes_available", "imagined_routes"]
