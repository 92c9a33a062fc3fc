"""Figures of Experiment 5 (Fig. 7.9, 7.10, the four situations, a retrieval film strip)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from ...analysis import figures
from ...analysis.figures import pyplot, save
from ...models.tool_use import N_POSTURES
from .config import THESIS

plt = pyplot()  # imported with this module, which only draws

COLOURS = {"behind": "tab:blue", "far": "tab:red"}


def _pc_rgb(img) -> np.ndarray:
    """A PC map (2, H, W) (toy, tool) as an RGB picture: toy red, tool green on white."""
    a = np.asarray(img, dtype=float)
    if a.max() > 1.0:
        a = a / 255.0
    toy, tool = a[0], a[1]
    rgb = np.ones(toy.shape + (3,))
    rgb[..., 1] -= toy
    rgb[..., 2] -= toy
    rgb[..., 0] -= tool
    rgb[..., 2] -= tool
    return rgb.clip(0, 1)


def success_curves(summary: dict, hypothesis: str, path: Path, xkey: str, xlabel: str, title: str) -> Path:
    """Success rate (%) per group, one panel per strategy, a line per situation (as Fig. 7.9/7.10)."""
    g = pd.DataFrame([r for r in summary["groups"] if r["hypothesis"] == hypothesis])
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
    for ax, strat in zip(axes, ("reactive", "planning")):
        for sit, s in g[g["strategy"] == strat].groupby("situation", sort=False):
            s = s.sort_values("level")
            x = s["age_months"] if xkey == "age" else s["level"]
            ax.plot(x, 100 * s["success_rate"], marker="o", color=COLOURS.get(sit), label=f"{sit} (this run)")
            th = THESIS[hypothesis][sit]
            if th:
                lv = sorted(th)
                xs = [int(s.loc[s["level"] == k, "age_months"].iloc[0]) if xkey == "age" and (s["level"] == k).any() else k
                      for k in lv]
                ax.plot(xs, [100 * th[k] for k in lv], ls="--", marker="x", color=COLOURS.get(sit), alpha=0.6,
                        label=f"{sit} (thesis)")
        ax.set_title(f"({'ab'[strat == 'planning']}) {strat} system", fontsize=9)
        ax.set_xlabel(xlabel)
        ax.set_ylim(-5, 105)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (%)")
    axes[1].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def situations_figure(views: dict, path: Path) -> Path | None:
    """The eye's view of the four initial situations with their colour-filtered PC maps (``views``:
    :func:`neuroimagery.experiments.exp5.protocol.situation_views`); none without the eye's images."""
    if views["eye"] is None:
        return None
    fig, axes = plt.subplots(2, N_POSTURES, figsize=(11, 4.6))
    for p in range(1, N_POSTURES + 1):
        axes[0, p - 1].imshow(views["eye"][p - 1])
        axes[0, p - 1].set_title(f"posture-{p}" + (" (tool behind toy)" if p == 1 else " (tool far from toy)" if p == 4 else ""),
                                 fontsize=8)
        axes[1, p - 1].imshow(_pc_rgb(views["pc"][p - 1].numpy()))
        for ax in axes[:, p - 1]:
            ax.set_xticks([])
            ax.set_yticks([])
    axes[0, 0].set_ylabel("eye (V1)", fontsize=8)
    axes[1, 0].set_ylabel("PC (colour filtered)", fontsize=8)
    return save(fig, path)


def filmstrip(film: dict, path: Path) -> Path:
    """One planning retrieval: at each step the imagined (C3) outcome beside the real one."""
    frames = film["frames"]
    n = len(frames) + 1
    fig, axes = plt.subplots(2, n, figsize=(2.6 * n, 4.4), squeeze=False)
    axes[0, 0].imshow(_pc_rgb(film["start"].numpy()))
    axes[0, 0].set_title("start (real)", fontsize=8)
    axes[1, 0].axis("off")
    for i, f in enumerate(frames, start=1):
        axes[0, i].imshow(_pc_rgb(f["imagined"].numpy()))
        axes[0, i].set_title(f"step {i}: {f['action']} imagined", fontsize=8)
        axes[1, i].imshow(_pc_rgb(f["real"].numpy()))
        axes[1, i].set_title(f"step {i}: {f['action']} real", fontsize=8)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    title = (f"{film['strategy']} child, tool {film['situation']} ({film['hypothesis']} level {film['level']}): "
             "mental image (top) vs the scene after really moving (bottom)")
    fig.suptitle(textwrap.fill(title, max(24, int(2.6 * n * 11))), fontsize=9)  # 9 pt: about 11 characters an inch
    return save(fig, path)


@figures.timed
def draw_all(cfg, run, df: pd.DataFrame, summary: dict, results: list[dict], views: dict | None = None) -> None:
    """Every figure and TensorBoard image of a run; ``views`` are the initial situations as the robot
    sees them (:func:`neuroimagery.experiments.exp5.protocol.situation_views`), none off the robot world."""
    figs = {}
    figs["fig_7_9"] = success_curves(summary, "hp1", run.figures / "fig_7_9_hp1_skills.png", "age",
                                     "age (months) = 2..6 IM detectors", "HP1: success vs number of skills")
    figs["fig_7_10"] = success_curves(summary, "hp2", run.figures / "fig_7_10_hp2_trials.png", "level",
                                      "training trials", "HP2: success vs training trials")
    log_training_curves(run.logger, results, df)
    film = next((d["film"] for d in results if d.get("film")), None)
    if film is not None:
        figs["filmstrip"] = filmstrip(film, run.figures / "retrieval_filmstrip.png")
        log_film(run.logger, film)
    if views is not None:
        p = situations_figure(views, run.figures / "situations.png")
        if p is not None:
            figs["situations"] = p
        for k in range(1, N_POSTURES + 1):
            run.logger.image(f"situations/posture-{k}", _pc_rgb(views["pc"][k - 1].numpy()), 0)
    summary["figures"] = {k: str(Path(v).relative_to(run.root)) for k, v in figs.items()}


def training_curves(results: list[dict]) -> dict[str, list[float]]:
    """The skill-learning curves of every robot's library, averaged per event over the skills that
    reached each step: ``pibb/<event>/cost`` per PI^BB update (the update's mean event cost,
    1 - successes / samples, in the order the updates ran) and ``competence/<event>`` per epoch of
    Fig. 7.5's stopping rule."""
    sums: dict[str, list[list[float]]] = {}

    def add(tag: str, values) -> None:
        acc = sums.setdefault(tag, [])
        for i, v in enumerate(values):
            if i == len(acc):
                acc.append([])
            acc[i].append(float(v))

    for d in results:
        for sk in (d.get("library") or {}).get("skills", []):
            add(f"pibb/{sk['event']}/cost", [1.0 - op[2] for op in sk["log"] if op[0] == "c1"])
            add(f"competence/{sk['event']}", sk["competence"])
    return {tag: [sum(v) / len(v) for v in acc] for tag, acc in sums.items()}


def sequencing_curves(df: pd.DataFrame) -> dict[str, list[float]]:
    """C4's learning over the training trials of Fig. 7.6 (HP2 groups), per situation and strategy,
    averaged over the robots whose group had trial n: ``sequencing/<situation>/<strategy>/success``
    (the share of robots
    whose trial n succeeded, really or in imagination) and ``.../q_max`` (the largest action value of
    the robot's skills at the start after trial n)."""
    out: dict[str, list[float]] = {}
    if "train_q" not in df:
        return out
    d = df[(df["hypothesis"] == "hp2") & (df["training_trials"] > 0)]
    for (sit, strat), g in d.groupby(["situation", "strategy"], sort=False):
        for col, name in (("train_successes", "success"), ("train_q", "q_max")):
            seqs = [[float(v) for v in str(x).split(">")] for x in g[col] if isinstance(x, str) and x]
            n = max((len(q) for q in seqs), default=0)
            out[f"sequencing/{sit}/{strat}/{name}"] = [float(np.mean([q[i] for q in seqs if len(q) > i]))
                                                       for i in range(n)]
    return out


def log_training_curves(logger, results: list[dict], df: pd.DataFrame | None = None) -> None:
    """:func:`training_curves` (and :func:`sequencing_curves` of ``df``) as TensorBoard scalars
    ``train/...`` over their own steps (from 1)."""
    curves = training_curves(results) | (sequencing_curves(df) if df is not None else {})
    for tag, ys in curves.items():
        for i, y in enumerate(ys):
            logger.scalar(f"train/{tag}", y, i + 1)


def log_film(logger, film: dict) -> None:
    """TensorBoard: the filmed retrieval step by step (``film/real``, ``film/imagined``: the PC map
    after each attempt and the mental image C3 gave for it; step 0 = the start) and the filmed
    child's weights after its test (``brain/C1/...``, ``brain/C2/...``, ``brain/C3/...``,
    ``brain/C4/...``; :meth:`ToolUseBrain.maps`)."""
    logger.text("film/child", f"{film['hypothesis']} level {film['level']}, tool {film['situation']}, "
                              f"{film['strategy']} child: " + " > ".join(f["action"] for f in film["frames"]), 0)
    logger.image("film/real", _pc_rgb(film["start"].numpy()), 0)
    for i, f in enumerate(film["frames"], start=1):
        logger.image("film/real", _pc_rgb(f["real"].numpy()), i)
        logger.image("film/imagined", _pc_rgb(f["imagined"].numpy()), i)
    logger.maps(film.get("maps", {}), prefix="brain/")  # absent in checkpoints written before the maps
