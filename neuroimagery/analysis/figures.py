"""Figures redrawn from a run (matplotlib, Agg backend). Models never draw; protocols pass data."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402


def rt_by_disparity(df: pd.DataFrame, path: str | Path, groups: Sequence[str] = ("test", "condition"),
                    title: str = "", ylabel: str = "RT", signed: bool = False, errorbars: bool = True) -> Path:
    """Mean RT (+- s.e.m. over participants) against disparity, one line per group."""
    fig, ax = plt.subplots(figsize=(6, 4))
    xcol = "signed_disparity" if signed and "signed_disparity" in df else "disparity"
    for key, g in df.groupby(list(groups), sort=False):
        per_p = g.groupby([xcol, "participant"])["rt"].mean().unstack()
        m = per_p.mean(axis=1)
        s = per_p.std(axis=1, ddof=1) / np.sqrt(per_p.shape[1]) if per_p.shape[1] > 1 else 0 * m
        label = "/".join(map(str, key)) if isinstance(key, tuple) else str(key)
        if errorbars:
            ax.errorbar(m.index, m.values, yerr=s.values, marker="o", capsize=3, label=label)
        else:
            ax.plot(m.index, m.values, marker="o", label=label)
    ax.set_xlabel("disparity (deg)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save(fig, path)


def rate_by_disparity(df: pd.DataFrame, path: str | Path, column: str = "correct", error: bool = True,
                      groups: Sequence[str] = ("test", "condition"), title: str = "") -> Path:
    """Error (or correct) rate against disparity, one line per group."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, g in df.groupby(list(groups), sort=False):
        r = g.groupby("disparity")[column].mean()
        r = 1 - r if error else r
        label = "/".join(map(str, key)) if isinstance(key, tuple) else str(key)
        ax.plot(r.index, 100 * r.values, marker="o", label=label)
    ax.set_xlabel("disparity (deg)")
    ax.set_ylabel(("error" if error else "correct") + " rate (%)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
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


def correct_bars(df: pd.DataFrame, path: str | Path, title: str, by: str = "test") -> Path:
    """Mean share of ``correct`` trials (+- SD over participants), in %, one bar per ``by`` group."""
    per = df.groupby([by, "participant"])["correct"].mean().unstack()
    order = [k for k in per.index]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    m, s = 100 * per.mean(axis=1), 100 * per.std(axis=1, ddof=1).fillna(0)
    ax.bar(range(len(order)), m.values, yerr=s.values, capsize=4)
    ax.set_xticks(range(len(order)), order)
    ax.set_ylabel("correct responses (%)")
    ax.set_ylim(0, 100)
    ax.set_title(title)
    return save(fig, path)


def save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return path
