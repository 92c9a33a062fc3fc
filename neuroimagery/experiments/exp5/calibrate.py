"""The Experiment 5 world's calibration: a written search over what the thesis leaves open.

    python -m neuroimagery.experiments.exp5.calibrate --storage FILE --stage screen --trials N
    python -m neuroimagery.experiments.exp5.calibrate --storage FILE --stage baseline | confirm | report

The plan (parameters, constraints, objective, the rule that picks the world, seeds, budget) is
docs/world_calibration.md, written before the search. The search's state is an Optuna journal
file (``--storage``): a rerun resumes it, and several workers may run on the same file at once
(give each its own ``--sampler-seed``). Each candidate's measured pieces are kept in the work
folder (``--work``, default ``FILE.d``), so a stopped trial is retried from where it stopped.

Stages: ``screen`` runs ``--trials`` trials: stage 1 rejects a candidate by forward kinematics
(``robot.world_candidate``, ``robot.pull_paths``), stage 2 screens the others (W1-W4 at screening
size, ``exp5.candidate``); ``baseline`` screens the present world the same way; ``confirm``
measures the ``--confirm`` best screened candidates at acceptance size on the calibration seeds
(``confirm-baseline`` the present world); ``report`` prints the history, the front and the budget.
HP1 and HP2 are never run.
"""
from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

from ...core.errors import UserInputError
from ...core.arguments import ToolParser, check, check_size, count, path, run_resumable, seed
from .calibration_report import screen_sizes, screened_at
from .candidate import SEED0, candidate_key, measure, rank_key

STUDY = "exp5-world"
SAMPLING = "posture-1-first"  # the postures' sampling (docs/world_calibration.md, third amendment)
STAGES = ("screen", "baseline", "confirm", "confirm-baseline", "report")
PULL_LIKE_MIN, BEHIND_MAX = 0.01, 0.15  # stage 1's pull-path thresholds (docs/world_calibration.md)


def _optuna():
    try:
        import optuna
    except ImportError:
        raise UserInputError("the calibration needs optuna: pip install 'neuroimagery[calibrate]'") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    return optuna


def open_study(storage: Path, sizes: dict, sampler_seed: int, check_sampling: bool = True, resize: bool = False):
    """The study in the journal ``storage`` (created with ``sizes`` if new; an existing one must have
    been screened at the same sizes, unless ``resize``: then its screens from now on have ``sizes``,
    the former ones are kept in ``sizes_history``, docs/world_calibration.md's fourth amendment)."""
    optuna = _optuna()
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    try:
        storage.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UserInputError(f"--storage {storage}: cannot make its folder: {err.strerror or err}") from None
    try:
        store = JournalStorage(JournalFileBackend(str(storage)))
        # stage 1's verdict is the trial's constraint (Trial.set_constraint from Optuna 5, else constraints_func)
        by_func = {} if hasattr(optuna.trial.Trial, "set_constraint") else dict(
            constraints_func=lambda t: t.user_attrs.get("constraint", [1.0]))
        sampler = optuna.samplers.TPESampler(seed=sampler_seed, multivariate=True, group=True, n_startup_trials=20,
                                             **by_func)
        study = optuna.create_study(study_name=STUDY, storage=store, load_if_exists=True, sampler=sampler,
                                    directions=["minimize", "maximize", "maximize"])
    except (ValueError, KeyError, TypeError) as err:
        raise UserInputError(f"--storage {storage} is not a calibration journal: {err}") from None
    except OSError as err:
        raise UserInputError(f"--storage {storage}: {err.strerror or err}") from None
    kept = study.user_attrs.get("sizes")
    if kept is None:
        from ...robot.world_candidate import PRESENT

        study.set_user_attr("sizes", sizes)
        study.set_user_attr("sampling", SAMPLING)
        study.enqueue_trial({k: v for k, v in PRESENT.items() if k != "grip_pivot_deg"})  # the first trial
    elif check_sampling and study.user_attrs.get("sampling") != SAMPLING:
        raise UserInputError(f"--storage {storage} was searched with another sampling of the postures "
                             f"({study.user_attrs.get('sampling')}, not {SAMPLING}): its trials are another search; "
                             "use a new journal")
    elif kept != sizes and resize and check_sampling:
        study.set_user_attr("sizes_history", study.user_attrs.get("sizes_history", [])
                            + [dict(sizes=kept, before_trial=len(study.get_trials(deepcopy=False)))])
        study.set_user_attr("sizes", sizes)
    elif kept != sizes:
        raise UserInputError(f"--storage {storage} was screened with {kept}, not {sizes}: "
                             "use its sizes, --resize, or another journal")
    return study


def suggest(trial) -> dict:
    """One candidate's parameters (``robot.world_candidate.PARAMETERS``)."""
    from ...robot.world_candidate import PARAMETERS

    p = {}
    for name, spec in PARAMETERS.items():
        if name == "grip_pivot_deg":
            p[name] = trial.suggest_float(name, *spec) if p["table_contact"] == "grip" else 10.0
        elif isinstance(spec[0], str):
            p[name] = trial.suggest_categorical(name, spec)
        else:
            p[name] = trial.suggest_float(name, *spec)
    return p


def stage1(p: dict, folder: Path, fk_movements: int) -> tuple:
    """The candidate's world and stage 1's verdict: (cfg, reasons it is rejected, pull paths)."""
    from ...robot.pull_paths import pull_paths
    from ...robot.world_candidate import build, reject_reasons

    placed: list = []
    cfg, bad = build(p, folder / "urdf", placed)
    bad = bad or reject_reasons(cfg)
    pulls = None
    if not bad:
        pulls = pull_paths(cfg, p["weight_sigma"], fk_movements, SEED0)
        if pulls["pull_like"] < PULL_LIKE_MIN:
            bad = [f"pull-like movements from posture 1: {pulls['pull_like']:.2%} (at least {PULL_LIKE_MIN:.0%})"]
        elif pulls["behind"] > BEHIND_MAX:
            bad = [f"pull paths behind from posture 4: {pulls['behind']:.0%} (at most {BEHIND_MAX:.0%})"]
    return cfg, bad, pulls, placed


def objective(trial, work: Path, sizes: dict):
    from ...robot.world_candidate import derived_rules

    t0 = time.process_time()
    p = suggest(trial)
    folder = work / candidate_key(p)
    cfg, bad, pulls, placed = stage1(p, folder, sizes["fk_movements"])
    trial.set_user_attr("pulls", pulls)
    trial.set_user_attr("placed", placed)
    trial.set_user_attr("reasons", bad)
    trial.set_user_attr("constraint", [float(len(bad))])
    if hasattr(trial, "set_constraint"):
        trial.set_constraint("stage1", float(len(bad)))
    if bad:
        trial.set_user_attr("stage", "rejected")
        trial.set_user_attr("cpu_s", round(time.process_time() - t0, 1))
        return 1.0, 0.0, 0.0
    trial.set_user_attr("derived", derived_rules(cfg))
    trial.set_user_attr("postures", [list(q) for q in cfg.postures])
    trial.set_user_attr("toy_xy", list(cfg.toy_xy))
    m = measure(cfg, p["weight_sigma"], folder, sizes["babble"], [SEED0], sizes["libraries"], [SEED0])
    trial.set_user_attr("sizes", sizes)
    trial.set_user_attr("stage", "screened")
    trial.set_user_attr("measures", m)
    trial.set_user_attr("cpu_s", round(time.process_time() - t0, 1))
    return m["w3"], m["w4"], float(m["w1"] + m["w2"])


def _line(study, trial) -> None:
    a = trial.user_attrs
    if a.get("stage") == "screened":
        m = a["measures"]
        what = f"screened: W1 {m['w1']}, W2 {m['w2']}, W3 {m['pull_alone']}/{m['with_pull']}, W4 {m['routes']}/{m['libraries']}"
    elif a.get("stage") == "rejected":
        what = "rejected: " + "; ".join(a.get("reasons", []))[:160]
    else:
        what = str(trial.state)
    print(f"trial {trial.number} ({a.get('cpu_s', '?')} CPU-s) {what}", flush=True)


def retry_failed(study) -> None:
    """Enqueue once, with the same parameters, each trial that failed (an interrupt): its kept
    pieces are reused."""
    optuna = _optuna()
    done = set(study.user_attrs.get("retried", []))
    failed = [t for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.FAIL,)) if t.number not in done]
    for t in failed:
        study.enqueue_trial(t.params)
    if failed:
        study.set_user_attr("retried", sorted(done | {t.number for t in failed}))


def rescreen_former(study, sizes: dict) -> None:
    """Enqueue once, with the same parameters, each candidate screened only at sizes other than
    ``sizes`` (a journal resized by the fourth amendment): its kept libraries are reused."""
    done = set(study.user_attrs.get("rescreened", []))
    now = {candidate_key(t.params) for t in screened_at(study, sizes)}
    former = [t for t in study.get_trials(deepcopy=False) if t.user_attrs.get("stage") == "screened"
              and screen_sizes(study, t) != sizes and t.number not in done and candidate_key(t.params) not in now]
    for t in former:
        study.enqueue_trial(t.params)
    if former:
        study.set_user_attr("rescreened", sorted(done | {t.number for t in former}))


def screen(study, work: Path, sizes: dict, trials: int) -> None:
    retry_failed(study)
    rescreen_former(study, sizes)
    study.optimize(lambda t: objective(t, work, sizes), n_trials=trials, callbacks=[_line],
                   show_progress_bar=sys.stderr.isatty())


def present(work: Path, sizes: dict, key: str, babble_seeds: int, library_seeds: int) -> dict:
    """The present world (docs/robot.md) measured as a candidate is, at ``sizes`` per seed."""
    from ...robot.config import WorldConfig

    t0 = time.process_time()
    m = measure(WorldConfig(), 300.0, work / key, sizes["babble"], list(range(SEED0, SEED0 + babble_seeds)),
                sizes["libraries"], list(range(SEED0, SEED0 + library_seeds)))
    return dict(m, cpu_s=round(time.process_time() - t0, 1))


def confirm(study, work: Path, sizes: dict, k: int, babble_seeds: int, library_seeds: int, at: dict) -> None:
    """The ``k`` best screened candidates (the rule, among the screens at the journal's ``sizes``) not
    yet confirmed, measured at ``at`` per seed (acceptance size, the fifth amendment) on the
    calibration seeds."""
    from ...robot.world_candidate import build

    done = {n for n in (a[len("confirmed_"):] for a in study.user_attrs) if n.isdigit()}
    screened = sorted(screened_at(study, sizes), key=lambda t: rank_key(t.user_attrs["measures"]))
    for t in [t for t in screened if str(t.number) not in done][:k]:
        t0 = time.process_time()
        folder = work / candidate_key(t.params | {"grip_pivot_deg": t.params.get("grip_pivot_deg", 10.0)})
        cfg, _ = build(t.params | {"grip_pivot_deg": t.params.get("grip_pivot_deg", 10.0)}, folder / "urdf")
        m = measure(cfg, t.params["weight_sigma"], folder, at["babble"], list(range(SEED0, SEED0 + babble_seeds)),
                    at["libraries"], list(range(SEED0, SEED0 + library_seeds)))
        study.set_user_attr(f"confirmed_{t.number}", dict(m, cpu_s=round(time.process_time() - t0, 1)))
        print(f"trial {t.number} confirmed: W1 {m['w1']}, W2 {m['w2']}, W3 {m['pull_alone']}/{m['with_pull']}, "
              f"W4 {m['routes']}/{m['libraries']}", flush=True)


MAX_TRIALS = 10_000  # per call without --allow-large
MAX_SIZE = {"babble": 100_000, "libraries": 1000, "fk_movements": 100_000}  # per seed, without --allow-large


def _path(text: str) -> Path:
    return Path(path(text))


def parse(argv):
    parser = ToolParser(prog="python -m neuroimagery.experiments.exp5.calibrate", description=__doc__.split("\n")[0])
    parser.add_argument("--storage", type=_path, required=True, help="Optuna journal file (created if absent; resumed)")
    parser.add_argument("--stage", choices=STAGES, default="screen", help="what to run (docs/world_calibration.md)")
    parser.add_argument("--trials", type=count, default=10, help="screen: trials to run in this call")
    parser.add_argument("--confirm", type=count, default=1, help="confirm: best screened candidates to confirm")
    parser.add_argument("--confirm-seeds", type=count, nargs=2, default=[10, 5], metavar=("BABBLE", "LIBRARY"),
                        help="confirm: calibration seeds of babbling and of libraries (acceptance size: 10 5)")
    parser.add_argument("--confirm-size", type=count, nargs=2, default=[10_000, 16], metavar=("BABBLE", "LIBRARIES"),
                        help="confirm: exploration movements per posture and libraries per seed (acceptance size)")
    parser.add_argument("--babble", type=count, default=2000, help="exploration movements per posture and seed")
    parser.add_argument("--libraries", type=count, default=8, help="skill libraries per seed")
    parser.add_argument("--fk-movements", type=count, default=2000, help="stage 1: movements of the pull paths")
    parser.add_argument("--sampler-seed", type=seed, default=0, help="the sampler's seed (one per worker)")
    parser.add_argument("--work", type=_path, default=None, help="folder of the kept pieces (default FILE.d)")
    parser.add_argument("--resize", action="store_true",
                        help="screen a journal of other sizes at these from now on (its former screens are screened again)")
    parser.add_argument("--allow-large", action="store_true", help="allow sizes past the limits of --help's defaults")
    args = parser.parse_args(argv)
    for name in ("trials", "confirm", "babble", "libraries", "fk_movements"):
        check(f"--{name.replace('_', '-')}", getattr(args, name), ge=1)
    check("--confirm-seeds", min(args.confirm_seeds), ge=1)
    check("--confirm-size", min(args.confirm_size), ge=1)
    check_size("--trials", args.trials, MAX_TRIALS, args.allow_large)
    for name, most in MAX_SIZE.items():
        check_size(f"--{name.replace('_', '-')}", getattr(args, name), most, args.allow_large)
    return args


def run(args) -> None:
    from .calibration_report import report

    if args.stage in ("confirm", "report") and not args.storage.is_file():
        raise UserInputError(f"--storage {args.storage}: no such journal (the stage {args.stage} reads a search)")
    sizes = dict(babble=args.babble, libraries=args.libraries, fk_movements=args.fk_movements)
    at = dict(babble=args.confirm_size[0], libraries=args.confirm_size[1])
    work = args.work or args.storage.with_name(args.storage.name + ".d")
    study = open_study(args.storage, sizes, args.sampler_seed, check_sampling=args.stage != "report",
                       resize=args.resize)
    work.mkdir(parents=True, exist_ok=True)
    if args.stage == "screen":
        screen(study, work, sizes, args.trials)
    elif args.stage == "baseline":
        if "baseline" not in study.user_attrs:
            study.set_user_attr("baseline", present(work, sizes, "present", 1, 1))
    elif args.stage == "confirm":
        confirm(study, work, sizes, args.confirm, *args.confirm_seeds, at=at)
    elif args.stage == "confirm-baseline":
        study.set_user_attr("confirmed_baseline", present(work, at, "present", *args.confirm_seeds))
    print(report(study))


def main(argv: list[str] | None = None) -> int:
    given: dict = {}

    def work(argv) -> None:
        given["args"] = parse(argv)
        run(given["args"])

    def kept() -> str:
        journal = given["args"].storage if "args" in given else "the journal"
        return f"the finished trials are kept in {journal} and their pieces in the work folder"

    return run_resumable(work, argv, kept, sigterm=True)


if __name__ == "__main__":
    raise SystemExit(main())
