"""Acceptance of the Exp 5 world at the level of skill libraries (docs/contracts.md, W2-W4).

    python -m neuroimagery.experiments.exp5.world --libraries N --out DIR [--seed S [S ...]] [--jobs J]

Acquires ``N`` skill libraries per seed as Fig. 7.5 does (all six IM detectors, the world and acquisition
settings of ``conf/experiment/exp5.yaml``, no brain: an event counts as mastered from a posture when
one of its skills achieved it there in its last competence check), then measures on the world
alone, before any action sequencing:

* Table 7.1, skills: for each posture and event, the share of the learnt skills of that event that
  achieve it from that posture (last competence check); *possible* above ``POSSIBLE_RATE``;
* Table 7.1, events as the robots met them: the share of libraries whose exploration fired the
  event from the posture;
* W3: the share of libraries whose learnt pull (a skill of "retrieve"), performed from posture 4,
  retrieves the toy;
* W4: the share of libraries with a move-then-pull route from posture 4: a skill of another event
  (touch included) that does not retrieve by itself, followed by a pull that does.

With several seeds the measures are pooled over all their libraries (W2-W4's sample: 16 libraries
on each of the seeds 0-4, docs/contracts.md) and each seed's are listed beside them.

The retrieve detector of the simulator is read here: this is analysis of the world, not a child's
perception. Writes ``DIR/world_libraries.json`` and ``.md``; each library is kept as it is done in
``DIR/libraries/`` and reused by a rerun with the same ``--out`` when the world's and acquisition's
settings are the same, so an interrupted or killed run resumes.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from ...core.arguments import ToolParser, check, check_jobs, check_size, count, path, run_resumable, seed
from ...core.errors import UserInputError
from ...core.files import kept_json, writable_folder, write_text
from ...core.workers import run_pieces
from ...models.tool_use import EVENTS
from ...core.resources import core_limit
from ...robot.config import TABLE_CONTACTS
from ...robot.babble import CURVE_THRESHOLDS, MAX_SEEDS, POSSIBLE_RATE, THESIS_SKILLS, agreement, wilson

SKILL_NAMES = ("P", "T", "S", "N", "W", "E")
OUTPUTS = ("world_libraries.json", "world_libraries.md")
LIBRARY_DIR = "libraries"


def _settings(table_contact: str) -> dict:
    """What a library depends on besides its seed: the world's and acquisition's settings."""
    from dataclasses import asdict

    from ...models.tool_use import AcquisitionParams
    from .config import WorldParams

    return dict(world=asdict(WorldParams(table_contact=table_contact)), acquisition=asdict(AcquisitionParams()))


def _kept_library(out: Path, seed: int, i: int, table_contact: str) -> dict:
    """Library ``i`` of ``seed``: the one kept in ``out/libraries/`` when its settings are the same,
    else acquired (:func:`_one_library`) and kept there at once."""
    return kept_json(out / LIBRARY_DIR / f"seed{seed}_{i:04d}.json", _settings(table_contact),
                     lambda: dict(_one_library(seed, i, table_contact), seed=seed))


def one_library(seed: int, i: int, table_contact: str = "lift", world_config=None, env_kwargs: dict | None = None) -> dict:
    """Library ``i`` of ``seed`` and its W2-W4 measures, in the world of ``WorldParams`` with the
    table rule ``table_contact``, or in ``world_config`` (a ``WorldConfig``) with the environment's
    ``env_kwargs`` updated (a candidate world of ``exp5.calibrate``)."""
    import torch

    from ...models.tool_use import AcquisitionParams, Outcomes, acquire_skills
    from .config import WorldParams
    from ...robot.environment import ToolWorldEnvironment

    torch.set_num_threads(1)
    w = WorldParams(table_contact=table_contact)
    env = ToolWorldEnvironment(world_config or w.world_config(), **{**w.env_kwargs(), **(env_kwargs or {})})
    try:
        g = torch.Generator().manual_seed(seed * 100003 + i)
        lib = acquire_skills(env, EVENTS, AcquisitionParams(), g, brain=None)
        outcomes = Outcomes(env, {s.name: s for s in lib.skills}, env.perceive)
        pulls = [s.name for s in lib.skills if s.event == "retrieve"]
        moves = [s.name for s in lib.skills if s.event != "retrieve"]
        pull_alone = any(outcomes.after(4, (a,)).retrieved for a in pulls)
        routes = sorted({a for a in moves for b in pulls
                         if not outcomes.after(4, (a,)).retrieved and outcomes.after(4, (a, b)).retrieved})
        return dict(library=i, skills={s.name: [bool(v) for v in s.succeeds_from] for s in lib.skills},
                    events_seen=[[int(c > 0) for c in row] for row in lib.events_seen], missing=lib.missing,
                    has_pull=bool(pulls), pull_alone_from_4=bool(pull_alone), move_then_pull_from_4=routes,
                    rollouts=lib.explore_rollouts + lib.learn_rollouts + outcomes.rollouts)
    finally:
        env.close()


_one_library = one_library  # the name the acceptance command calls (tests replace it)


def summarise(libs: list[dict]) -> dict:
    n = len(libs)
    skills, events = {}, {}
    for p in range(4):
        row_s, row_e = [], []
        for k, e in enumerate(EVENTS):
            of_e = [ok[p] for lib in libs for name, ok in lib["skills"].items() if name.rstrip("0123456789") == e]
            row_s.append(round(sum(of_e) / len(of_e), 4) if of_e else 0.0)
            row_e.append(round(sum(lib["events_seen"][p][k] for lib in libs) / n, 4))
        skills[f"posture-{p + 1}"], events[f"posture-{p + 1}"] = row_s, row_e
    with_pull = [lib for lib in libs if lib["has_pull"]]
    alone = sum(lib["pull_alone_from_4"] for lib in with_pull)
    route = sum(bool(lib["move_then_pull_from_4"]) for lib in libs)
    return dict(
        libraries=n, possible_rate=POSSIBLE_RATE, skill_rates=skills, event_shares=events,
        skill_cells={k: [int(r > POSSIBLE_RATE) for r in v] for k, v in skills.items()},
        skill_agreement={str(t): agreement(skills, THESIS_SKILLS, t) for t in CURVE_THRESHOLDS},
        with_pull=len(with_pull), pull_alone_from_4=alone,
        pull_alone_share=round(alone / len(with_pull), 4) if with_pull else None,
        pull_alone_ci95=[round(v, 4) for v in wilson(alone, len(with_pull))],
        move_then_pull=route, move_then_pull_share=round(route / n, 4),
        move_then_pull_ci95=[round(v, 4) for v in wilson(route, n)],
        route_moves={e: sum(any(a.rstrip("0123456789") == e for a in lib["move_then_pull_from_4"]) for lib in libs)
                     for e in EVENTS[1:]},
        missing={e: sum(e in lib["missing"] for lib in libs) for e in EVENTS})


def markdown(s: dict) -> str:
    head = "| posture | " + " | ".join(SKILL_NAMES) + " | agree |\n|---|" + "---|" * 7 + "\n"
    rows = "".join(
        f"| {k} | " + " | ".join(f"{r:.2f}{'' if int(r > s['possible_rate']) == t else ' *'}"
                                 for r, t in zip(v, THESIS_SKILLS[k]))
        + f" | {sum(int(r > s['possible_rate']) == t for r, t in zip(v, THESIS_SKILLS[k]))}/6 |\n"
        for k, v in s["skill_rates"].items())
    curve = " | ".join(f"{float(t):.1%}: {a}" for t, a in s["skill_agreement"].items())
    return (f"### Skills from {s['libraries']} libraries (share of each event's skills achieving it from the posture)\n\n"
            + head + rows + f"\n`*`: differs from thesis Table 7.1 at \"possible\" = above {s['possible_rate']:.0%}. "
            f"Cells agreeing at other thresholds: {curve}.\n\n"
            f"- pull alone retrieves from posture 4: {s['pull_alone_from_4']} of {s['with_pull']} libraries with a pull "
            f"({s['pull_alone_share']}, 95 % [{s['pull_alone_ci95'][0]}, {s['pull_alone_ci95'][1]}])\n"
            f"- a move-then-pull route from posture 4: {s['move_then_pull']} of {s['libraries']} libraries "
            f"({s['move_then_pull_share']}, 95 % [{s['move_then_pull_ci95'][0]}, {s['move_then_pull_ci95'][1]}]); "
            f"first moves: {s['route_moves']}\n- events never found: {s['missing']}\n")


def per_seed(libs: list[dict]) -> list[dict]:
    """W2-W4 of each seed's libraries alone."""
    rows = []
    for seed in sorted({lib["seed"] for lib in libs}):
        s = summarise([lib for lib in libs if lib["seed"] == seed])
        rows.append(dict(seed=seed, libraries=s["libraries"], skill_cells=s["skill_agreement"][str(POSSIBLE_RATE)],
                         with_pull=s["with_pull"], pull_alone_from_4=s["pull_alone_from_4"],
                         move_then_pull=s["move_then_pull"]))
    return rows


def seed_table(rows: list[dict]) -> str:
    return ("| seed | libraries | skill cells agreeing (W2) | a pull alone retrieves from posture 4 (W3) "
            "| a move-then-pull route (W4) |\n|---|---|---|---|---|\n"
            + "".join(f"| {r['seed']} | {r['libraries']} | {r['skill_cells']} | {r['pull_alone_from_4']} of "
                      f"{r['with_pull']} | {r['move_then_pull']} |\n" for r in rows))


MAX_LIBRARIES = 1000  # per seed without --allow-large


def _parser() -> ToolParser:
    parser = ToolParser(prog="python -m neuroimagery.experiments.exp5.world", description=__doc__.split("\n")[0])
    parser.add_argument("--libraries", type=count, default=16, help="skill libraries to acquire per seed")
    parser.add_argument("--seed", type=seed, nargs="+", default=[0],
                        help="one seed or several (their libraries pooled, each seed's measures listed)")
    parser.add_argument("--jobs", type=count, default=None, help="worker processes (default: 2, or 1 on one core)")
    parser.add_argument("--out", type=lambda t: Path(path(t)), required=True,
                        help="output folder (rerun with the same folder to resume)")
    parser.add_argument("--allow-large", action="store_true",
                        help=f"allow more than {MAX_LIBRARIES} libraries per seed, {MAX_SEEDS} seeds or more "
                        "workers than cores")
    parser.add_argument("--table-contact", choices=TABLE_CONTACTS, default="lift",
                        help="how the table meets the rake (experiment.world.table_contact; docs/robot.md)")
    return parser


def parse(argv):
    args = _parser().parse_args(argv)
    check("--libraries", args.libraries, ge=1)
    check_size("--libraries", args.libraries, MAX_LIBRARIES, args.allow_large, "libraries acquired per seed")
    check_size("--seed: the number of seeds", len(args.seed), MAX_SEEDS, args.allow_large)
    if args.jobs is None:
        args.jobs = min(2, core_limit()[0])
    check_jobs("--jobs", args.jobs, args.allow_large)
    if len(set(args.seed)) != len(args.seed):
        raise UserInputError(f"--seed: each seed once, got {' '.join(map(str, args.seed))}")
    return args


def main(argv: list[str] | None = None) -> int:
    given: dict = {}

    def work(argv) -> None:
        args = given["args"] = parse(argv)
        writable_folder(args.out, OUTPUTS)
        t0 = time.perf_counter()
        pieces = [(args.out, seed, i, args.table_contact) for seed in args.seed for i in range(args.libraries)]
        libs = run_pieces(_kept_library, pieces, args.jobs, "libraries", " library")
        s = summarise(libs)
        seeds = per_seed(libs)
        text = markdown(s) + ("\n" + seed_table(seeds) if len(seeds) > 1 else "")
        write_text(args.out / OUTPUTS[0], json.dumps(dict(summary=s, per_seed=seeds, libraries=libs), indent=1))
        write_text(args.out / OUTPUTS[1], text)
        print(text)
        print(f"wrote {args.out / 'world_libraries.json'} in {time.perf_counter() - t0:.0f} s")

    def kept() -> str:
        where = given["args"].out / LIBRARY_DIR if "args" in given else "the output folder"
        return f"the finished libraries are kept in {where}"

    return run_resumable(work, argv, kept)


if __name__ == "__main__":
    raise SystemExit(main())
