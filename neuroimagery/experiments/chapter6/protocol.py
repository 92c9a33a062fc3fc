"""Trial-loop pieces shared by Experiments 3 and 4 (thesis chapter 6).

* the stimulus bank: edge maps of every item of a set, computed once per run and shared by all
  participants (they see the same screen);
* the trial table of a test (every pair of every object) and its ``trials.csv`` rows;
* the three-dot training set of the forward models (thesis Fig. 6.3, 6.8);
* the generalisation check of the forward models (IoU of imagined vs. true rotated edge maps);
* sample-trial logging and the step-by-step map panels (Fig. 6.12-6.13);
* progress bars (``neuroimagery.core.progress``): the forward models' mini-batches and the posture maps
  while training, the trials of each test block while testing.

Nothing here knows a model's internals: models return tensors, this module turns them into rows.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd
import torch

from ...core import progress
from ...core.errors import UserInputError
from ...nn import seeding
from ...nn.binary import ActiveRows, active_units
from ...analysis import figures
from ...analysis.summary import TRIAL_COLUMNS

TRAIN_LOOK_STREAM = 7  # the stream of the training looks (one per training image)
TEST_LOOK_STREAM = 200  # + test index: the looks a test builds
TRIAL_LOOK_STREAM = 300  # + test index: which look each trial takes


def gaze_errors(seed: int, stream: int, n: int, sd: float) -> np.ndarray | None:
    """``(n, 2)`` gaze errors (pan, tilt) in degrees, N(0, sd^2), from the run's seed and a stream."""
    if sd <= 0:
        return None
    g = seeding.participant_generators(seed, [0], stream=stream)[0]
    return (sd * torch.randn(n, 2, generator=g, dtype=torch.float64)).numpy()


# ---------------------------------------------------------------------------------- vision
def _vision():
    import neuroimagery.vision as v

    return v


def _vfun(name: str):
    """A function of the vision package (top level if exported, else its ``edges`` module)."""
    v = _vision()
    if hasattr(v, name):
        return getattr(v, name)
    from ...vision import edges

    return getattr(edges, name)


def stimulus_set(cfg, builtin: str, use_user_folder: bool = True):
    """The builtin set ``builtin``, or the user's folder (with the builtin set's protocol)."""
    from ...vision.stimulus_sets import get_stimulus_set, resolve_stimulus_set

    if use_user_folder:
        return resolve_stimulus_set(cfg.stimuli, builtin)
    return get_stimulus_set(builtin)


def make_eye(cfg):
    v = _vision()
    if hasattr(v, "make_eye"):
        return v.make_eye(cfg.vision)
    from ...vision.eye import make_eye as mk

    return mk(cfg.vision)


@dataclass
class StimulusBank:
    """Edge maps ``(N, size*size)`` of every item of a set, with an item -> row index."""

    set: object
    items: list
    maps: torch.Tensor
    index: dict
    looks: torch.Tensor | None = None  # (L, N, size*size): L looks at every item (rule R4), or None

    @classmethod
    def build(cls, eye, sset, size: int, errors: np.ndarray | None = None, looks: int = 0) -> "StimulusBank":
        """Edge maps of every item of ``sset``; with gaze ``errors`` ``(max(looks, 1) * N, 2)`` (deg),
        ``maps`` is the first look and ``looks`` holds ``looks`` looks per item."""
        items = [tuple(it) for it in sset.items()]
        L = max(int(looks), 1)
        maps = eye.edge_maps(sset, items=items * L, size=size, gaze_errors=errors) if errors is not None \
            else eye.edge_maps(sset, items=items, size=size)
        if maps.shape[0] != len(items) * (L if errors is not None else 1):
            raise UserInputError(f"stimulus set {sset.name!r}: the eye returned {maps.shape[0]} maps for {len(items)} items")
        if float(maps.sum()) == 0:
            raise UserInputError(f"stimulus set {sset.name!r}: no edges found in any image (are the shapes red or dark?)")
        flat = maps.reshape(-1, len(items), size * size).float()
        return cls(sset, items, flat[0], {it: i for i, it in enumerate(items)}, flat if looks > 0 and errors is not None else None)

    def trial_maps(self, rows: torch.Tensor, generators) -> torch.Tensor:
        """The maps ``(P, B, n)`` the trials ``rows`` ``(B,)`` see, one per participant (``generators``):
        a look drawn for every trial and participant when the bank holds looks, else the fixed map."""
        P = len(generators)
        if self.looks is None:
            return self.maps[rows].unsqueeze(0).expand(P, -1, -1)
        pick = torch.stack([torch.randint(self.looks.shape[0], (len(rows),), generator=g) for g in generators])
        return self.looks[pick, rows.unsqueeze(0).expand(P, -1)]

    def structure(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """How the set is built, per row: object index (long), mirror appearance (bool) and angle
        (deg), what a training rule may know of its own training set."""
        names = {o: k for k, o in enumerate(dict.fromkeys(it[0] for it in self.items))}
        mirror = self.set.appearances[1] if len(self.set.appearances) > 1 else None
        return (torch.tensor([names[it[0]] for it in self.items], dtype=torch.long),
                torch.tensor([it[2] == mirror for it in self.items], dtype=torch.bool),
                torch.tensor([float(it[1]) for it in self.items]))

    def angle_labels(self, unit_angles: Sequence[float]) -> torch.Tensor:
        """Unit index of each item's angle in ``unit_angles`` (the posture a wrist would hold)."""
        lut = {float(a): k for k, a in enumerate(unit_angles)}
        return torch.tensor([lut[float(it[1])] for it in self.items], dtype=torch.long)


def trial_table(bank: StimulusBank, test: str, condition: str) -> pd.DataFrame:
    """One row per pair of the set (every object), with the bank rows of its two maps."""
    rows = []
    for obj in bank.set.objects:
        for pr in bank.set.pairs(obj):
            r = dict(pr)
            r["test"], r["condition"] = test, condition
            r["target_row"] = bank.index[(pr["target_object"], float(pr["target_angle"]), pr["target_appearance"])]
            r["rotated_row"] = bank.index[(pr["rotated_object"], float(pr["rotated_angle"]), pr["rotated_appearance"])]
            rows.append(r)
    df = pd.DataFrame(rows)
    df["disparity"] = (df["rotated_angle"] - df["target_angle"]).abs().round().astype(int)
    return df


def angle_aligned(final, target, atol: float = 1e-6) -> np.ndarray:
    """Whether orientations ``final`` and ``target`` (deg) coincide on the circle: their difference
    modulo 360 is 0, so an image turned the long way round (e.g. -45 deg reached as 315 deg) counts
    as aligned."""
    diff = np.asarray(final, dtype=float) - np.asarray(target, dtype=float)
    return np.abs((diff + 180.0) % 360.0 - 180.0) <= atol


def trial_rows(table: pd.DataFrame, out: dict, participants: Sequence[int]) -> pd.DataFrame:
    """``trials.csv`` rows of a batched run: ``out`` holds ``(P, B)`` tensors from a model.

    ``rotated_ok``: the seen object's orientation plus the model's total rotation equals the
    target's orientation modulo 360 deg."""
    P, B = len(participants), len(table)
    flat = lambda v: v.reshape(-1).numpy()  # noqa: E731  (P, B) -> participant after participant
    df = table.drop(columns=["target_row", "rotated_row"]).iloc[np.tile(np.arange(B), P)].reset_index(drop=True)
    df.insert(0, "participant", np.repeat(np.array([int(p) for p in participants], dtype=np.int64), B))
    final = df["rotated_angle"].to_numpy() + flat(out["rotation_deg"])
    df["answer"] = np.where(flat(out["answer"]) == 0, "yes", "no")
    df["correct"] = (df["answer"] == "yes") == df["same"].astype(bool)
    df["rotation_steps"] = flat(out["rotation_steps"]).astype(int)
    df["rotated_ok"] = angle_aligned(final, df["target_angle"].to_numpy())
    df["rt"] = flat(out["rt"])
    for extra in ("decided", "rotations"):
        if extra in out:
            df[extra] = flat(out[extra])
    if len(table):
        progress.advance(B * P, note=f"{table['test'].iloc[0]}/{table['condition'].iloc[0]}")
    return df[TRIAL_COLUMNS + [c for c in ("decided", "rotations") if c in out]]


def batches_bar(what: str):
    """A progress wrapper for a model's training loop (``progress=`` of its fit methods)."""
    unit = "map" if what == "posture maps" else "batch"
    return lambda it: progress.bar(it, what=what, unit=unit)


def three_dot_training_set(generators, n: int, angles: Sequence[float], size: int, inner: int,
                           offsets: Sequence[int] | None = None):
    """Forward-model training pairs for each participant (Fig. 6.3, 6.8), as dense 0/1 rows: the
    pairs of :func:`three_dot_training_rows`. Returns ``X (P, n, in)``, ``Y (P, n, size*size)``,
    ``moves (P, n)``."""
    X, Y, moves = three_dot_training_rows(generators, n, angles, size, inner, offsets)
    return X.rows(0, n), Y.rows(0, n), moves


ROTATE_CHUNK = 4096  # three-dot maps rotated at a time (a dense float block of 16 MiB at 32x32)


def three_dot_training_rows(generators, n: int, angles: Sequence[float], size: int, inner: int,
                            offsets: Sequence[int] | None = None):
    """Forward-model training pairs for each participant (Fig. 6.3, 6.8), by their active units.

    Per image a rotation is drawn at random (the randomly selected movement of the thesis); the
    input is the three-dot image (placed in input block ``offsets[m]`` if given) and the target
    the same image rotated by ``angles[m]``. Each participant's generator draws the dot centres
    of its ``n`` images, then their movements. Returns ``X`` and ``Y``, :class:`ActiveRows`
    ``(P, n, in)`` and ``(P, n, size*size)``, and ``moves (P, n)``.
    """
    v = _vision()
    centres, moves = [], []
    for g in generators:
        centres.append(v.three_dot_centres(n, g, size, inner))
        moves.append(torch.randint(len(angles), (n,), generator=g))
    c, m = torch.stack(centres).reshape(-1, 3, 2), torch.stack(moves)
    ang = torch.tensor([float(a) for a in angles])[m.reshape(-1)]
    xs, ys = [], []
    for s in range(0, c.shape[0], ROTATE_CHUNK):  # a few dense blocks at a time, kept by their active units
        x = v.three_dot_maps(c[s:s + ROTATE_CHUNK], size, dtype=torch.bool)
        xs.append(active_units(x.reshape(x.shape[0], -1)))
        ys.append(active_units(_vfun("rotate")(x, ang[s:s + ROTATE_CHUNK]).reshape(x.shape[0], -1)))
    P, ss = len(generators), size * size
    X, Y = _padded(xs).reshape(P, n, -1), _padded(ys).reshape(P, n, -1)
    if offsets is None:
        return ActiveRows(X, ss), ActiveRows(Y, ss), m
    block = torch.tensor([int(o) for o in offsets])[m].unsqueeze(-1) * ss
    X = torch.where(X >= 0, X + block, X).to(torch.int16 if len(angles) * ss <= torch.iinfo(torch.int16).max else torch.int32)
    return ActiveRows(X, len(angles) * ss), ActiveRows(Y, ss), m


def _padded(parts: list[torch.Tensor]) -> torch.Tensor:
    """Active-unit indices ``(N_k, D_k)`` joined into ``(sum N_k, max D_k)``, -1 padding the narrower."""
    D = max(p.shape[1] for p in parts)
    return torch.cat([torch.nn.functional.pad(p, (0, D - p.shape[1]), value=-1) for p in parts])


def generalisation_iou(step_fn, bank: StimulusBank, angle: float, steps: int = 3, size: int = 32) -> dict:
    """Mean IoU between the imagined map after ``k`` steps of ``step_fn`` and the truly rotated
    edge map (``vision.rotate`` of the seen map by ``k * angle``), per participant and overall.

    ``step_fn(maps (P, B, n)) -> (P, B, n)`` is one forward-model step of a trained model.
    """
    rotate, iou = _vfun("rotate"), _vfun("iou")
    x = bank.maps
    cur = x.unsqueeze(0)
    res = {}
    for k in range(1, steps + 1):
        cur = step_fn(cur if cur.shape[0] > 1 else cur)
        truth = rotate(x.reshape(-1, size, size), k * angle)
        v = iou(cur.reshape(cur.shape[0], -1, size, size), truth.unsqueeze(0))  # (P, B)
        res[str(k)] = round(float(v.mean()), 4)
    return res


def sample_generators(seed: int, participants: Sequence[int], stream: int):
    return seeding.participant_generators(seed, list(participants), stream=stream)


def sample_names(table: pd.DataFrame, rows: Sequence[int]) -> list[str]:
    """``same_135deg`` / ``mirror_135deg`` names of the sample trials ``rows``."""
    t = table.iloc[list(rows)]
    return [f"{'same' if s else 'mirror'}_{int(d)}deg" for s, d in zip(t["same"].astype(bool), t["disparity"])]


CANDIDATES_PER_SAMPLE = 8  # trials recorded per sample trial shown, among which the shown ones are chosen
PER_DISPARITY = 2  # same pairs and mirror pairs recorded per disparity


def candidate_rows(table: pd.DataFrame, n: int) -> list[int]:
    """The rows recorded step by step so that ``n`` sample trials can be chosen after the test
    (:func:`choose_samples`): from the largest disparity down, ``PER_DISPARITY`` same and as many
    mirror pairs of each disparity, spread evenly over the table's order (first and last, ...), ``CANDIDATES_PER_SAMPLE * n`` rows at most. The labels
    only choose what is recorded; the model runs every trial alike."""
    if n <= 0 or table.empty:
        return []
    out: list[int] = []
    for d in sorted(set(table["disparity"]), reverse=True):
        at = table[table["disparity"] == d]
        for same in (True, False):
            rows = at.index[at["same"].astype(bool) == same]
            for row in rows[np.unique(np.linspace(0, len(rows) - 1, min(PER_DISPARITY, len(rows))).round().astype(int))]:
                if len(out) < CANDIDATES_PER_SAMPLE * n:
                    out.append(int(table.index.get_loc(row)))
    return out


def choose_samples(table: pd.DataFrame, out: dict, candidates: Sequence[int], n: int) -> tuple[list[int], str]:
    """The ``n`` most informative of the recorded ``candidates`` (rows of ``table``) for
    participant 0, whose maps are recorded: trials that rotated (at least one move that was not
    "still") and decided before the step limit, at the largest disparity first, a same pair then a
    mirror pair, alternating. Where too few did both, trials that rotated, then the rest, fill up.
    Returns the positions in ``candidates`` and a sentence saying how they were chosen."""
    if n <= 0 or not len(candidates):
        return [], ""
    rot = out["rotations"][0].reshape(-1)
    dec = out["decided"][0].reshape(-1)
    t = table.iloc[list(candidates)]
    info = [(2 if int(rot[r]) > 0 and bool(dec[r]) else 1 if int(rot[r]) > 0 else 0) for r in candidates]
    order = sorted(range(len(candidates)), key=lambda k: (-info[k], -float(t["disparity"].iloc[k]), k))
    same = [bool(v) for v in t["same"]]
    chosen: list[int] = []
    while len(chosen) < n and order:
        best = order[0]  # after a same pair a mirror pair, and back, where one is as informative
        alt = next((k for k in order if not chosen or same[k] != same[chosen[-1]]), best)
        pick = alt if info[alt] == info[best] else best
        chosen.append(pick)
        order.remove(pick)
    got = [info[k] for k in chosen]
    why = "participant 0's trials that rotated and decided, largest disparity first"
    if got and min(got) < 2:
        why += (f"; of the {len(candidates)} recorded ({PER_DISPARITY} same and {PER_DISPARITY} mirror pairs of each "
                "disparity, largest first) "
                f"{got.count(2)} shown did, {got.count(1)} rotated without deciding, {got.count(0)} never rotated")
    return chosen, why


def sample_history(table: pd.DataFrame, out: dict, candidates: Sequence[int], n: int) -> dict:
    """The sample trials of one test and condition from a run that recorded ``candidates``
    (:func:`candidate_rows`): ``{"names", "trials", "why"}`` of the ``n`` chosen by
    :func:`choose_samples`; pops ``out["history"]``."""
    history = out.pop("history")
    chosen, why = choose_samples(table, out, candidates, n)
    return {"names": sample_names(table, [candidates[k] for k in chosen]), "trials": [history[k] for k in chosen],
            "why": why}


def log_history(logger, history: list, prefix: str, names: Sequence[str] | None = None) -> None:
    """Every map of every step of the recorded sample trials to TensorBoard, as image series whose
    step is the rotation step (1 = the first)."""
    for trial_k, steps in enumerate(history):
        name = names[trial_k] if names is not None else f"trial{trial_k}"
        for s, maps in enumerate(steps):
            logger.maps({k: torch.as_tensor(v) for k, v in maps.items()}, step=s + 1, prefix=f"{prefix}/{name}/")


def sample_panels(path, key: str, history: list, names: Sequence[str], units=None, why: str = ""):
    """One figure of the sample trials of ``key``: one row per rotation step of each trial, the
    labels of the units of ``units`` (``{map: [label, ...]}``) under their columns, and ``why``
    (how the trials were chosen) under the title."""
    steps, labels = [], []
    for name, trial in zip(names, history):
        for i, st in enumerate(trial):
            steps.append({k: torch.as_tensor(v).numpy() for k, v in st.items()})
            labels.append(f"{name.replace('_', ' ')}, step {i + 1}")
    if not steps:
        return None
    title = f"{key}: sample trials, one row per rotation step" + (f"\nchosen: {why}" if why else "")
    return figures.map_panels(steps, path, title=title, row_labels=labels, units=units)


def training_bank(cfg, eye) -> StimulusBank:
    """The edge maps of the training set ``cfg.experiment.train_set`` (never the user's folder): one
    look per image from the training stream (rule R4)."""
    e = cfg.experiment
    sset = stimulus_set(cfg, e.train_set, use_user_folder=False)
    errors = gaze_errors(cfg.seed, TRAIN_LOOK_STREAM, len(list(sset.items())), e.percept.gaze_error_deg)
    return StimulusBank.build(eye, sset, e.map_size, errors)


def test_bank(cfg, eye, sset, k: int) -> StimulusBank:
    """The looks test ``k`` builds at the items of ``sset`` (rule R4), from the test's own stream."""
    e = cfg.experiment
    L = int(e.percept.looks)
    errors = gaze_errors(cfg.seed, TEST_LOOK_STREAM + k, max(L, 1) * len(list(sset.items())), e.percept.gaze_error_deg)
    return StimulusBank.build(eye, sset, e.map_size, errors, looks=L)


def trial_looks(cfg, bank: StimulusBank, table: pd.DataFrame, ids, k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(target, rotated) maps ``(P, B, n)`` of the trials of ``table`` in test ``k``: each participant's
    trial takes its own look at each object (rule R4)."""
    gens = seeding.participant_generators(cfg.seed, list(ids), stream=TRIAL_LOOK_STREAM + k)
    rows_t = torch.as_tensor(table["target_row"].to_numpy().copy())
    rows_r = torch.as_tensor(table["rotated_row"].to_numpy().copy())
    return bank.trial_maps(rows_t, gens), bank.trial_maps(rows_r, gens)


def train_posture_maps(cfg, eye, model, angles: Sequence[float], generators, bank: StimulusBank | None = None):
    """Train the model's posture maps (``model.fit_posture_maps``) on the training set (``bank``, by
    default :func:`training_bank`) labelled by the nearest of ``angles``, then put ``model`` in eval
    mode for testing; returns ``model``."""
    bank = training_bank(cfg, eye) if bank is None else bank
    model.fit_posture_maps(bank.maps, bank.angle_labels(angles), generators, progress=batches_bar("posture maps"))
    return model.eval()


def save_model(run, name: str, model, ids) -> None:
    """Checkpoint ``model`` of participants ``ids`` as ``checkpoints/<name>.pt``."""
    run.save_checkpoint(name, {"state_dict": model.state_dict(), "participants": list(ids)})


def load_model(checkpoint_dir, name: str, build):
    """Rebuild a model with ``build(participant_ids)`` from a training run, in eval mode for testing."""
    from ...core.checkpoints import load_checkpoint

    ck = load_checkpoint(checkpoint_dir, name)
    model = build(ck["participants"])
    model.load_state_dict(ck["state_dict"])
    return model.eval()


def add_time_outs(tests: dict, df: pd.DataFrame) -> dict:
    """Add to each ``"<test>/<condition>"`` entry of ``tests`` the share of its trials that reached the
    step limit (``time_out_rate``: Exp 4's random answers, Exp 3's forced NO), from the ``decided``
    column of ``trials.csv``; returns ``{key: share}``."""
    out = {}
    if "decided" not in df:
        return out
    for (test, cond), g in df.groupby(["test", "condition"], sort=False):
        share = round(float(1.0 - g["decided"].astype(bool).mean()), 4)
        key = f"{test}/{cond}"
        if key in tests:
            tests[key]["time_out_rate"] = share
        out[key] = share
    return out


def error_split(tests: dict) -> str:
    """'recog/none: NO to same 12.0 %, YES to mirror 0.5 %; ...' from summary tests."""
    pct = lambda v: "-" if v is None else f"{100 * v:.1f} %"
    return "; ".join(f"{k}: NO to same pairs {pct(v.get('error_rate_same'))}, YES to mirror pairs "
                     f"{pct(v.get('error_rate_different'))}" for k, v in tests.items() if k.endswith("/none"))
