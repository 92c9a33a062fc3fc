"""Figures redrawn from a run (matplotlib, Agg backend). Models never draw; protocols pass data.

Every curve and bar is the mean over participants of each participant's mean, with error bars of
one standard error of that mean over participants (``SEM``); the thesis's stated values are drawn
dashed in black (``thesis=``), labelled "thesis"."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402


THESIS_STYLE = dict(color="black", linestyle="--", linewidth=1.2)


def participant_means(g: pd.DataFrame, by: str, value: str) -> tuple[pd.Series, pd.Series]:
    """Mean over participants of each participant's mean ``value`` per level of ``by``, and its
    standard error over participants (0 with one participant)."""
    per_p = g.groupby([by, "participant"])[value].mean().unstack()
    m = per_p.mean(axis=1)
    s = per_p.std(axis=1, ddof=1) / np.sqrt(per_p.shape[1]) if per_p.shape[1] > 1 else 0 * m
    return m, s.fillna(0.0)


def _label(key) -> str:
    return "/".join(map(str, key)) if isinstance(key, tuple) else str(key)


def _thesis_points(ax, thesis: Mapping[str, Sequence[tuple[float, float]]] | None, scale: float = 1.0) -> None:
    """The thesis's stated values: ``{label: [(x, y), ...]}``, dashed black (one point: a dashed ring)."""
    for i, (label, pts) in enumerate((thesis or {}).items()):
        xs, ys = zip(*pts)
        ys = [scale * y for y in ys]
        if len(pts) == 1:
            ax.plot(xs, ys, marker="o", markersize=9, markerfacecolor="none", label=f"thesis: {label}", **THESIS_STYLE)
        else:
            ax.plot(xs, ys, label=f"thesis: {label}", **THESIS_STYLE)


def _finish(ax, xlabel: str, ylabel: str, title: str) -> None:
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.grid(alpha=0.3)


def rt_by_disparity(df: pd.DataFrame, path: str | Path, groups: Sequence[str] = ("test", "condition"),
                    title: str = "", ylabel: str = "RT", signed: bool = False, errorbars: bool = True,
                    thesis: Mapping[str, Sequence[tuple[float, float]]] | None = None, x: str | None = None,
                    xlabel: str = "disparity (deg)") -> Path:
    """Mean RT (+- SEM over participants) against disparity (or the column ``x``), one line per group."""
    fig, ax = plt.subplots(figsize=(6, 4))
    xcol = x or ("signed_disparity" if signed and "signed_disparity" in df else "disparity")
    for key, g in df.groupby(list(groups), sort=False):
        m, s = participant_means(g, xcol, "rt")
        if errorbars:
            ax.errorbar(m.index, m.values, yerr=s.values, marker="o", capsize=3, label=_label(key))
        else:
            ax.plot(m.index, m.values, marker="o", label=_label(key))
    _thesis_points(ax, thesis)
    _finish(ax, xlabel, ylabel, title)
    return save(fig, path)


def rate_by_disparity(df: pd.DataFrame, path: str | Path, column: str = "correct", error: bool = True,
                      groups: Sequence[str] = ("test", "condition"), title: str = "",
                      thesis: Mapping[str, Sequence[tuple[float, float]]] | None = None) -> Path:
    """Error (or correct) rate (+- SEM over participants) against disparity, one line per group."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, g in df.groupby(list(groups), sort=False):
        v = g[column].astype(float)
        m, s = participant_means(g.assign(_v=1.0 - v if error else v), "disparity", "_v")
        ax.errorbar(m.index, 100 * m.values, yerr=100 * s.values, marker="o", capsize=3, label=_label(key))
    _thesis_points(ax, thesis, scale=100.0)
    _finish(ax, "disparity (deg)", ("error" if error else "correct") + " rate (%)", title)
    return save(fig, path)


def rate_bars(df: pd.DataFrame, path: str | Path, title: str = "", by: str = "test", column: str = "correct",
              error: bool = False, thesis: Mapping[str, float] | None = None) -> Path:
    """Correct (or error) rate per level of ``by`` (+- SEM over participants); the thesis's value of a
    level, where it states one, as a dashed black line across its bar."""
    v = df[column].astype(float)
    m, s = participant_means(df.assign(_v=1.0 - v if error else v), by, "_v")
    order = list(dict.fromkeys(df[by]))
    m, s = m.reindex(order), s.reindex(order)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.bar(range(len(order)), 100 * m.values, yerr=100 * s.values, capsize=4, color="tab:blue", label="this run")
    shown = False
    for i, k in enumerate(order):
        if thesis and k in thesis:
            ax.hlines(100 * thesis[k], i - 0.4, i + 0.4, label=None if shown else "thesis", **THESIS_STYLE)
            shown = True
    ax.set_xticks(range(len(order)), order)
    ax.set_ylabel(("error" if error else "correct") + " rate (%)")
    ax.set_ylim(0, 100)
    ax.set_title(title)
    ax.legend(fontsize=7)
    return save(fig, path)


def map_panels(steps: Sequence[Mapping[str, np.ndarray]], path: str | Path, title: str = "",
               row_labels: Sequence[str] | None = None) -> Path:
    """A grid of map activities: one row per step, one column per map (as Fig. 5.4, 6.12)."""
    names = list(steps[0].keys())
    fig, axes = plt.subplots(len(steps), len(names), figsize=(1.6 * len(names), 1.6 * len(steps)), squeeze=False)
    for r, st in enumerate(steps):
        for c, n in enumerate(names):
            a = np.asarray(st[n], dtype=float)
            if a.ndim == 1:
                a = a[None, :]
            ax = axes[r, c]
            ax.imshow(a, cmap="viridis", aspect="auto", interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(n, fontsize=7)
            if c == 0 and row_labels is not None:
                ax.set_ylabel(row_labels[r], fontsize=7)
    fig.suptitle(title, fontsize=9)
    return save(fig, path)


def save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return path
