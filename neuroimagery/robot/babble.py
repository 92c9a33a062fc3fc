"""Measure Table 7.1 (events part) as rates, by random motor babbling from each initial posture.

    python -m neuroimagery.robot.babble --rollouts N --seeds K --out DIR [--jobs J]

For each of ``K`` seeds (0 .. K-1) and each posture, ``N`` random DMPs are rolled out (the thesis's
way of drawing them, ``robot.movements``: random goals and shape, noise added to the goals) with
no event watched, so every event that happens is recorded. An event's rate from a posture is the
share of the ``N K`` rollouts that fired it, with a 95 % Wilson interval. An event is *possible*
from a posture when its rate is above ``POSSIBLE_RATE`` (docs/robot.md: fixed before measuring);
the agreement with thesis Table 7.1 is also given at other thresholds (a curve), so that the count
does not hinge on that one choice. Writes ``DIR/table_7_1.json``: per posture ``events`` (0/1 at
``POSSIBLE_RATE``), ``rates``, ``rates_ci95`` ([low, high] per event), ``rates_per_seed``,
``rollouts``; and ``agreement`` (cells agreeing with the thesis at each threshold). ``DIR/table_7_1.md``
sets it beside the thesis's table. Each posture and seed's counts are kept in ``DIR/counts/`` as they
are done and reused by a rerun with the same ``--out`` and the same settings, so an interrupted or
killed run resumes; ``--jobs`` runs postures and seeds in parallel (the same counts).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from functools import partial
from pathlib import Path

import torch

from neuroimagery.core.arguments import (ToolParser, check, check_jobs, check_size, count, path as nonempty_path,
                                    run_resumable)
from neuroimagery.core.errors import UserInputError
from neuroimagery.core.files import kept_json, writable_folder, write_text
from neuroimagery.core.workers import run_pieces
from neuroimagery.robot.movements import MovementConfig, explore, random_primitives, trajectories, world_dmp
from neuroimagery.robot.config import TABLE_CONTACTS, WorldConfig
from neuroimagery.robot.events import EVENTS
from neuroimagery.robot.world import ToolWorld
from neuroimagery.core.thesis import EXP5_TABLE_7_1

# Table 7.1 of the thesis (line 1439), events and skills, from neuroimagery.core.thesis
THESIS_EVENTS = {k: v["events"] for k, v in EXP5_TABLE_7_1.items()}
THESIS_SKILLS = {k: v["skills"] for k, v in EXP5_TABLE_7_1.items()}
# "possible" = rate above 1 %: an event that rare is still met with probability 0.63 by a robot's
# exploration of about 100 movements from a posture (400 over four postures); docs/robot.md
POSSIBLE_RATE = 0.01
CURVE_THRESHOLDS = (0.0, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1)


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion ``k / n``."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def agreement(rates: dict[str, list[float]], thesis: dict[str, list[int]], threshold: float) -> int:
    """Cells whose "rate above ``threshold``" equals the thesis's 0/1."""
    return sum(int(r > threshold) == t for k in thesis for r, t in zip(rates[k], thesis[k]))


def babble_counts(world: ToolWorld, posture: int, n: int, seed: int, cfg: MovementConfig) -> list[int]:
    """Event counts of ``n`` random DMPs from ``posture`` (the stream of seed ``seed`` and posture)."""
    dmp = world_dmp()
    gen = torch.Generator().manual_seed(seed * 1009 + posture)
    counts = [0] * len(EVENTS)
    q0 = world.initial_posture(posture)
    for start in range(0, n, 50):
        theta = explore(world, dmp, random_primitives(world, dmp, min(50, n - start), cfg, gen), q0, gen)
        for o in world.rollout(trajectories(world, dmp, theta, q0, cfg), posture, watched=None):
            for k, f in enumerate(o.events):
                counts[k] += int(f)
    return counts


COUNTS_DIR = "counts"


def _piece(posture: int, n: int, seed: int, cfg: MovementConfig, config: WorldConfig, out: Path | None,
           world: ToolWorld | None = None) -> list[int]:
    """:func:`babble_counts` of one posture and seed, kept in ``out/counts/`` (when ``out``) and
    reused from there when it was computed with the same settings. Without ``world``, one is made
    with ``config`` for this piece alone (a worker process)."""
    from dataclasses import asdict

    def compute() -> list[int]:
        w = world or ToolWorld(config)
        try:
            return babble_counts(w, posture, n, seed, cfg)
        finally:
            if world is None:
                w.close()

    if out is None:
        return compute()
    settings = dict(posture=posture, seed=seed, rollouts=n, movements=asdict(cfg), world=asdict(config))
    return kept_json(out / COUNTS_DIR / f"posture{posture}_seed{seed}.json", settings, compute)


kept_counts = _piece  # the public name (exp5.calibrate's candidates)


def measure(n_rollouts: int, seeds: int = 3, cfg: MovementConfig | None = None, world: ToolWorld | None = None,
            table_contact: str = "lift", out: Path | None = None, jobs: int = 1) -> dict:
    """Babble ``n_rollouts`` times per seed from each posture; the table (see module docstring).
    Without ``world``, one with the table rule ``table_contact`` (``WorldConfig``). With ``out``,
    each posture and seed's counts are kept there and reused (:func:`_piece`); ``jobs`` > 1 runs
    them in worker processes, each with its own world (not with ``world``)."""
    if n_rollouts < 1:
        raise UserInputError(f"--rollouts must be >= 1, got {n_rollouts}")
    if seeds < 1:
        raise UserInputError(f"--seeds must be >= 1, got {seeds}")
    if jobs < 1:
        raise UserInputError(f"--jobs must be >= 1, got {jobs}")
    if jobs > 1 and world is not None:
        raise ValueError("measure: jobs > 1 makes a world per worker; pass no world")
    cfg = cfg or MovementConfig()
    config = world.cfg if world is not None else WorldConfig(table_contact=table_contact)
    keys = [(k, s) for k in range(1, 5) for s in range(seeds)]
    pieces = [(k, n_rollouts, s, cfg, config, out) for k, s in keys]
    if jobs == 1:
        own = world is None
        world = world or ToolWorld(config)
        try:
            found = run_pieces(partial(_piece, world=world), pieces, 1, "postures x seeds")
        finally:
            if own:
                world.close()
    else:
        found = run_pieces(_piece, pieces, jobs, "postures x seeds")
    counts = dict(zip(keys, found))
    table: dict = {}
    for k in range(1, 5):
        per_seed = [counts[(k, s)] for s in range(seeds)]
        total = [sum(c[i] for c in per_seed) for i in range(len(EVENTS))]
        n = n_rollouts * seeds
        rates = [c / n for c in total]
        table[f"posture-{k}"] = {
            "events": [int(r > POSSIBLE_RATE) for r in rates],
            "rates": [round(r, 5) for r in rates],
            "rates_ci95": [[round(v, 5) for v in wilson(c, n)] for c in total],
            "rates_per_seed": [[round(c[i] / n_rollouts, 5) for i in range(len(EVENTS))] for c in per_seed],
            "rollouts": n,
        }
    rates = {k: v["rates"] for k, v in table.items()}
    return {**table, "possible_rate": POSSIBLE_RATE, "seeds": seeds,
            "agreement": {str(t): agreement(rates, THESIS_EVENTS, t) for t in CURVE_THRESHOLDS}}


def markdown(table: dict) -> str:
    """Measured rates beside the thesis's cells (``*`` = disagrees at ``POSSIBLE_RATE``) and the curve."""
    head = "| posture | " + " | ".join(EVENTS) + " | agree |\n|---|" + "---|" * (len(EVENTS) + 1) + "\n"
    rows = []
    for key in THESIS_EVENTS:
        row, thesis = table[key], THESIS_EVENTS[key]
        cells = [f"{r:.1%} [{lo:.1%}, {hi:.1%}]{'' if m == t else '*'}"
                 for m, t, r, (lo, hi) in zip(row["events"], thesis, row["rates"], row["rates_ci95"])]
        rows.append(f"| {key} | " + " | ".join(cells) + f" | {sum(m == t for m, t in zip(row['events'], thesis))}/6 |\n")
    curve = ("| threshold | " + " | ".join(f"{float(t):.1%}" for t in table["agreement"]) + " |\n|---|"
             + "---|" * len(table["agreement"]) + "\n| cells agreeing (of 24) | "
             + " | ".join(str(v) for v in table["agreement"].values()) + " |\n")
    thesis_rows = "".join(f"| {k} | " + " | ".join(map(str, v)) + " |\n" for k, v in THESIS_EVENTS.items())
    return (f"### Measured (random babbling, {table['posture-1']['rollouts']} rollouts per posture)\n\n" + head
            + "".join(rows) + f"\nCells: rate of rollouts that fired the event, 95 % interval; `*`: differs from "
            f"thesis Table 7.1 with \"possible\" = rate above {table['possible_rate']:.0%}.\n\n"
            "### Agreement at other thresholds\n\n" + curve
            + "\n### Thesis Table 7.1, events\n\n| posture | " + " | ".join(EVENTS) + " |\n|---|"
            + "---|" * len(EVENTS) + "\n" + thesis_rows)


OUTPUTS = ("table_7_1.json", "table_7_1.md")


def check_out(out: Path) -> Path:
    """``--out`` before the first rollout (:func:`~neuroimagery.core.files.writable_folder`)."""
    return writable_folder(out, OUTPUTS)


def write_outputs(out: Path, table: dict) -> None:
    """The table and its markdown into ``out``, each atomically. A failed write keeps the computed
    table: it goes to a file of the system's temporary folder, named in the error."""
    path = out / OUTPUTS[0]
    try:
        write_text(path, json.dumps(table, indent=2))
        path = out / OUTPUTS[1]
        write_text(path, markdown(table))
    except OSError as err:
        kept = ""
        try:
            fd, spare = tempfile.mkstemp(prefix="table_7_1-", suffix=".json")
            with os.fdopen(fd, "w") as f:
                f.write(json.dumps(table, indent=2))
            kept = f"; the computed table is kept in {spare}"
        except OSError:
            pass
        raise UserInputError(f"cannot write {path}: {err.strerror or err}{kept}") from None


# the most rollouts per posture and seed, and seeds, without --allow-large: a rollout is a physics
# simulation of a movement (tens of ms), so these already take hours
MAX_ROLLOUTS = 100_000
MAX_SEEDS = 100


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line, every value checked (a :class:`UserInputError` naming the option)."""
    parser = ToolParser(prog="python -m neuroimagery.robot.babble", description=__doc__.split("\n")[0])
    parser.add_argument("--rollouts", type=count, default=1000, help="random DMPs per posture and seed")
    parser.add_argument("--seeds", type=count, default=3, help="seeds 0 .. K-1")
    parser.add_argument("--out", type=lambda t: Path(nonempty_path(t)), required=True,
                        help="output folder (rerun with the same folder to resume)")
    parser.add_argument("--jobs", type=count, default=1, help="worker processes (the same counts)")
    parser.add_argument("--allow-large", action="store_true",
                        help=f"allow more than {MAX_ROLLOUTS} rollouts per posture and seed, {MAX_SEEDS} seeds or "
                        "more workers than cores")
    parser.add_argument("--table-contact", choices=TABLE_CONTACTS, default="lift",
                        help="how the table meets the rake (WorldConfig.table_contact; docs/robot.md)")
    args = parser.parse_args(argv)
    check_jobs("--jobs", args.jobs, args.allow_large)
    for name, value, most in (("--rollouts", args.rollouts, MAX_ROLLOUTS), ("--seeds", args.seeds, MAX_SEEDS)):
        check(name, value, ge=1)
        check_size(name, value, most, args.allow_large,
                   f"it would run {args.rollouts * args.seeds * len(THESIS_EVENTS):.3g} physics rollouts")
    return args


def main(argv: list[str] | None = None) -> int:
    given: dict = {}

    def work(argv) -> None:
        args = given["args"] = parse(argv)
        t0 = time.perf_counter()
        check_out(args.out)
        table = measure(args.rollouts, args.seeds, table_contact=args.table_contact, out=args.out, jobs=args.jobs)
        write_outputs(args.out, table)
        print(markdown(table))
        print(f"wrote {args.out / 'table_7_1.json'} in {time.perf_counter() - t0:.1f} s")

    def kept() -> str:
        where = given["args"].out / COUNTS_DIR if "args" in given else "the output folder"
        return f"the finished postures x seeds are kept in {where}"

    return run_resumable(work, argv, kept)


if __name__ == "__main__":
    raise SystemExit(main())
