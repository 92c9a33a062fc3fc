"""Pieces shared by the chapter-5 mental-rotation experiments (Experiments 1 and 2).

* the stimuli: edge maps (32x32, {0, 1}) of the upside-down L (object A) and its mirror
  (object B), or of a user's folder, through the project's vision pipeline;
* the trial table -> summary -> report plumbing common to both experiments;
* their progress bars: the training stages, and the trials of each test block
  (``neuroimagery.core.progress``).
"""
from __future__ import annotations

import functools
from typing import Sequence

import numpy as np
import pandas as pd
import torch

from ...core import progress
from ...analysis.summary import TRIAL_COLUMNS, check_trials
from ...nn.functional import intra_op_threads
from ...nn.numerics import flush_subnormals


# ---------------------------------------------------------------------------------- stimuli
def stimulus_set(cfg):
    """The L set (Exp. 1-2) or the user's folder set when ``cfg.stimuli.kind == 'folder'``."""
    from ...vision.stimulus_sets import get_stimulus_set, resolve_stimulus_set

    if getattr(cfg.stimuli, "kind", "builtin") == "folder":
        return resolve_stimulus_set(cfg.stimuli, "L")
    return get_stimulus_set("L")


def edge_maps(cfg, sset, items: Sequence[tuple[str, float]]) -> torch.Tensor:
    """Binary edge maps ``(N, 32, 32)`` of ``(object, angle)`` items (first appearance)."""
    app = sset.appearances[0]
    full = [(o, float(a), app) for o, a in items]
    try:  # the eye of the vision package (direct or camera path), when it offers one
        from ...vision import make_eye  # type: ignore

        return make_eye(cfg.vision).edge_maps(sset, items=full, size=32).float()
    except ImportError:
        from ...vision.edges import edge_pipeline

        imgs = [sset.image(o, a, ap) for o, a, ap in full]
        return edge_pipeline(imgs, size=32, red_threshold=cfg.vision.red_threshold).float()


def objects_of(sset) -> list[str]:
    """The two objects the chapter-5 models are trained on (A and its mirror B for the L set)."""
    objs = list(sset.objects)
    if len(objs) < 2:
        raise ValueError(f"stimulus set {sset.name!r} needs two objects (a shape and its mirror), has {objs}")
    return objs[:2]


# --------------------------------------------------------------------------------- threads
def auto_threads(fn):
    """Run ``fn(cfg, ...)`` on ``cfg.experiment.auto_threads`` intra-op threads when the run leaves
    ``threads`` at 0 and that key is above 0; at 0 (the default) on the run's own setting, the
    cores left free by other work when the run started (:func:`neuroimagery.core.threads.auto_threads`).
    ``auto_threads=1`` keeps the loops of small products on one thread for a machine whose other
    work starts after the run (a second thread then mostly waits for the other's share).

    Subnormal floats are flushed to zero meanwhile (:func:`~neuroimagery.nn.numerics.flush_subnormals`):
    the population codes' Gaussian tails fall below 1.2e-38, and the products over them (M1_1's
    weights and winner table, the Hebbian closed forms' decay products) otherwise run up to thirty
    times slower; only values below that size change."""

    @functools.wraps(fn)
    def wrapper(cfg, *args, **kwargs):
        with flush_subnormals():
            if getattr(cfg, "threads", 0) or not cfg.experiment.auto_threads:
                return fn(cfg, *args, **kwargs)
            with intra_op_threads(cfg.experiment.auto_threads):
                return fn(cfg, *args, **kwargs)

    return wrapper


# --------------------------------------------------------------------------------- trials
def image_table(cfg, sset, angles: Sequence[float]) -> dict:
    """Edge maps of every (object, angle) of the L set, keyed ``(object index, angle)``, flattened."""
    objs = objects_of(sset)
    items = [(o, float(a)) for o in objs for a in angles]
    maps = edge_maps(cfg, sset, items).reshape(len(items), -1)
    return {(objs.index(o), a): maps[i] for i, (o, a) in enumerate(items)}


def train_and_save(cfg, run, model_cls, e, angles: Sequence[float]):
    """Train ``model_cls(e, participants, seed)`` on the L set at ``angles`` and checkpoint it."""
    from ...vision.stimulus_sets import get_stimulus_set

    model = model_cls(e, cfg.participants, cfg.seed)
    with progress.bar(total=2, what="stimuli, model", unit="stage") as stages:
        images = image_table(cfg, get_stimulus_set("L"), angles)
        stages.update()
        model.fit(images)
        stages.update()
    if hasattr(model, "compact_state"):  # the factors the weights are formed from, not the weights
        run.save_checkpoint("model", model.compact_state())
    else:
        run.save_checkpoint("model", {"state_dict": model.state_dict(), "participants": cfg.participants})
    return model


def load_model(cfg, checkpoint_dir, model_cls, e):
    """The model of a training run's ``checkpoints/model.pt``, in eval mode.

    Reads the full form ``{"state_dict", "participants"}`` and, for models that write one, the
    compact form ``{"format": model_cls.CHECKPOINT_FORMAT, ...}`` (weights formed again from the
    trainer's factors and the initial weights of the checkpoint's seed)."""
    from pathlib import Path

    from ...core.errors import UserInputError
    from ...core.checkpoints import load_checkpoint

    path = Path(checkpoint_dir) / "checkpoints" / "model.pt"
    state = load_checkpoint(checkpoint_dir, "model")
    compact = getattr(model_cls, "CHECKPOINT_FORMAT", None)
    if isinstance(state, dict) and "format" not in state and "state_dict" in state:
        model = model_cls(e, state["participants"], cfg.seed)
        model.load_state_dict(state["state_dict"])
    elif isinstance(state, dict) and compact is not None and state.get("format") == compact:
        model = model_cls(e, state["participants"], state["seed"])  # the initial weights the factors start from
        try:
            model.load_compact_state(state)
        except ValueError as err:
            raise UserInputError(f"checkpoint {path}: {err}") from err
        model.seed = cfg.seed  # the test's own random streams follow the run's seed, as with a full checkpoint
    else:
        fmt = state.get("format") if isinstance(state, dict) else type(state).__name__
        known = "a full state_dict checkpoint" + (f" or format {compact!r}" if compact else "")
        raise UserInputError(f"checkpoint {path}: unknown format {fmt!r} ({model_cls.__name__} reads {known})")
    model.eval()
    return model


def count_trials(rows: list[dict], test: str, condition: str = "none") -> list[dict]:
    """The rows of one test block, counted on the test phase's progress bar; returns ``rows``."""
    progress.advance(len(rows), note=f"{test}/{condition}")
    return rows


def trials_frame(rows: list[dict]) -> pd.DataFrame:
    """Rows -> the trials table of docs/results.md (columns in the public order, extras after)."""
    df = pd.DataFrame(rows)
    for c in TRIAL_COLUMNS:
        if c not in df:
            df[c] = np.nan
    return check_trials(df)


def pearson(x: Sequence[float], y: Sequence[float]) -> float | None:
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return None
    return float(np.corrcoef(x, y)[0, 1])


def to_np(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().float().numpy()


def record_figures_and_scalars(run, summary: dict, shown: dict, tests: dict, prefix: str) -> dict:
    """Store the figure paths ``shown`` (relative to the run) in ``summary["figures"]``; returns
    ``summary``. The tests' figures reach TensorBoard as HParams metrics and its text summary (the
    run's headline, :func:`neuroimagery.analysis.summary.headline`), not as one-point scalars."""
    summary["figures"] = {k: str(v.relative_to(run.root)) for k, v in shown.items()}
    return summary


def finish_report(r, cfg, run, summary: dict, custom_limit: str) -> None:
    """Close a chapter-5 report: the user-stimulus section (with ``custom_limit``, why these
    object-specific models cannot really rotate an unseen shape), the figures, and the
    reproducibility note; then write ``report.md``."""
    from ...analysis.report import reproducibility_note

    c = summary["tests"].get("custom/none")
    if c is not None:
        r.user_stimuli(summary, cfg.stimuli.path, "It replaces no set: the built-in L set (objects A and B) is "
                       "tested as usual, and the folder's first two shapes (a shape and its mirror) beside it.",
                       "The model is trained on the L set, as in every run.")
        r.h("User stimuli")
        r.p(f"Rotation success {100 * c['rotation_success_rate']:.1f} %, correct answers "
            f"{100 * c['correct_rate']:.1f} %. " + custom_limit)
    r.h("Figures")
    r.figures(run.root, [run.root / v for v in summary.get("figures", {}).values()])
    r.p(reproducibility_note(cfg.seed))
    r.write(run.report_path)
