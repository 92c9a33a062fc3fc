"""Figures redrawn from a run (matplotlib, Agg backend). Models never draw; protocols pass data.

Every curve and bar is the mean over participants of each participant's mean, with error bars of
one standard error of that mean over participants (``SEM``); the thesis's stated values are drawn
dashed in black (``thesis=``), labelled "thesis". matplotlib is imported by :func:`pyplot`, when
the first figure is drawn."""
from __future__ import annotations

import functools
import textwrap
import time
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from ..core.files import save_figure
from ..core.logger import COLOUR_MAP, own_range

if TYPE_CHECKING:
    import pandas as pd


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend, imported with the first figure (a run imports no
    plotting library before it draws)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt

THESIS_STYLE = dict(color="black", linestyle="--", linewidth=1.2)

_SPENT = [0.0, 0]  # seconds spent in timed drawing functions, and the nesting depth


def drawing_time() -> float:
    """Seconds this process has spent in functions marked :func:`timed` (this module's drawing and
    saving functions, the experiments' figure routines); a run's ``runtime_s.figures`` is the
    difference over its evaluation."""
    return _SPENT[0]


def timed(draw):
    """Count ``draw``'s wall time in :func:`drawing_time` (once when drawing functions nest); an
    experiment's own figure routine wears it too, so its plotting before :func:`save` counts."""
    @functools.wraps(draw)
    def wrapper(*args, **kwargs):
        _SPENT[1] += 1
        t0 = time.perf_counter()
        try:
            return draw(*args, **kwargs)
        finally:
            _SPENT[1] -= 1
            if _SPENT[1] == 0:
                _SPENT[0] += time.perf_counter() - t0
    return wrapper


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


@timed
def rt_by_disparity(df: pd.DataFrame, path: str | Path, groups: Sequence[str] = ("test", "condition"),
                    title: str = "", ylabel: str = "RT", signed: bool = False, errorbars: bool = True,
                    thesis: Mapping[str, Sequence[tuple[float, float]]] | None = None, x: str | None = None,
                    xlabel: str = "disparity (deg)") -> Path:
    """Mean RT (+- SEM over participants) against disparity (or the column ``x``), one line per group."""
    plt = pyplot()
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


@timed
def rate_by_disparity(df: pd.DataFrame, path: str | Path, column: str = "correct", error: bool = True,
                      groups: Sequence[str] = ("test", "condition"), title: str = "",
                      thesis: Mapping[str, Sequence[tuple[float, float]]] | None = None) -> Path:
    """Error (or correct) rate (+- SEM over participants) against disparity, one line per group."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, g in df.groupby(list(groups), sort=False):
        v = g[column].astype(float)
        m, s = participant_means(g.assign(_v=1.0 - v if error else v), "disparity", "_v")
        ax.errorbar(m.index, 100 * m.values, yerr=100 * s.values, marker="o", capsize=3, label=_label(key))
    _thesis_points(ax, thesis, scale=100.0)
    _finish(ax, "disparity (deg)", ("error" if error else "correct") + " rate (%)", title)
    return save(fig, path)


@timed
def rate_bars(df: pd.DataFrame, path: str | Path, title: str = "", by: str = "test", column: str = "correct",
              error: bool = False, thesis: Mapping[str, float] | None = None) -> Path:
    """Correct (or error) rate per level of ``by`` (+- SEM over participants); the thesis's value of a
    level, where it states one, as a dashed black line across its bar."""
    plt = pyplot()
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


CELL = 48  # pixels of one map's cell in a panel grid
GAP = 4  # pixels between cells
BAR_MIN = 130  # pixels: the shortest colour bar of a panel grid (its two-line label fits beside it)


def _cell(a: np.ndarray) -> np.ndarray:
    """A map scaled to [0, 1] by its own range and resampled by nearest neighbour onto a
    ``CELL x CELL`` square (a 1-D map onto a strip a third as tall, across the middle); NaN
    around it (drawn blank)."""
    a = own_range(a)  # the colour scale of the TensorBoard images
    if a.ndim == 1:
        a = a[None, :]
    h, w = a.shape
    rows = CELL // 3 if h == 1 else CELL
    img = a[np.arange(rows) * h // rows][:, np.arange(CELL) * w // CELL]
    out = np.full((CELL, CELL), np.nan)
    r0 = (CELL - rows) // 2
    out[r0:r0 + rows] = img
    return out


@timed
def map_panels(steps: Sequence[Mapping[str, np.ndarray]], path: str | Path, title: str = "",
               row_labels: Sequence[str] | None = None, units: Mapping[str, Sequence[str]] | None = None) -> Path:
    """A grid of map activities: one row per step, one column per map (as Fig. 5.4, 6.12), drawn
    as one mosaic at its own pixel size (each map scaled by its own range, viridis, blank around
    it), with the map names above, the row labels on the left, a colour bar on the right and, for
    the 1-D maps named in ``units``, each unit's label under its column (e.g. PMCm: l, s, r);
    cheap however long the trial."""
    plt = pyplot()
    names = list(steps[0].keys())
    units = {n: list(u) for n, u in (units or {}).items() if n in names}
    R, C = len(steps), len(names)
    pitch = CELL + GAP
    mosaic = np.full((R * pitch - GAP, C * pitch - GAP), np.nan)
    for r, st in enumerate(steps):
        for c, n in enumerate(names):
            mosaic[r * pitch:r * pitch + CELL, c * pitch:c * pitch + CELL] = _cell(st[n])
    rgba = plt.get_cmap(COLOUR_MAP)(np.nan_to_num(mosaic))
    rgba[np.isnan(mosaic)] = 1.0
    # float32 colours: matplotlib resamples the mosaic at its own size in the array's precision, and
    # every colour of the map (and the blank) turns into the same bytes from float32 as from float64
    rgba = rgba.astype(np.float32)
    dpi, left, right = 100, 170, 120
    H, W = mosaic.shape
    bar_h = max(min(H, 240), BAR_MIN)  # the colour bar, tall enough for its label
    bottom = (40 if units else 10) + max(0, bar_h - H)
    fw = W + left + right
    width = max(20, int(fw / 6.5))  # characters of a 9-pt line that fit the figure's width
    title = "\n".join(textwrap.fill(line, width) for line in title.split("\n"))
    names_h = int(0.71 * 6.5 * max(map(len, names))) + 16  # the map names, 7 pt at 45 deg (6.5 px a character at most)
    top = max(56, names_h + 16) + 16 * (title.count("\n") + 1)
    fh = H + top + bottom
    fig = plt.figure(figsize=(fw / dpi, fh / dpi), dpi=dpi)
    fig.figimage(rgba, xo=left, yo=bottom, origin="upper")
    fig.text(0.5, 1 - 8 / fh, title, ha="center", va="top", fontsize=9)
    for c, n in enumerate(names):
        fig.text((left + c * pitch + CELL / 2) / fw, (bottom + H + 6) / fh, n, ha="left", va="bottom", fontsize=7,
                 rotation=45)
    for r, lab in enumerate(row_labels if row_labels is not None else []):
        fig.text((left - 6) / fw, (bottom + H - r * pitch - CELL / 2) / fh, lab, ha="right", va="center", fontsize=7)
    for c, n in enumerate(names):
        labs = units.get(n)
        if labs:
            w = len(labs)
            for k, lab in enumerate(labs):
                fig.text((left + c * pitch + (k + 0.5) * CELL / w) / fw, (bottom - 4) / fh, lab, ha="center",
                         va="top", fontsize=6, rotation=90 if w > 3 or max(map(len, labs)) > 3 else 0)
    cax = fig.add_axes([(left + W + 14) / fw, (bottom + H - bar_h) / fh, 12 / fw, bar_h / fh])
    bar = fig.colorbar(plt.cm.ScalarMappable(cmap=COLOUR_MAP, norm=plt.Normalize(0, 1)), cax=cax)
    bar.set_ticks([0, 0.5, 1], labels=["min", "", "max"])
    bar.ax.tick_params(labelsize=6)
    bar.set_label("activity, each map\nscaled to its own range", fontsize=6)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=dpi, metadata={"Software": None})
    plt.close(fig)
    return path


def _overlap(a, b, pad: float = 0.5) -> bool:
    return a.x0 < b.x1 - pad and b.x0 < a.x1 - pad and a.y0 < b.y1 - pad and b.y0 < a.y1 - pad


def _crowded(ax, renderer) -> list:
    labels = [t for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
    boxes = [t.get_window_extent(renderer) for t in labels]
    return labels if any(_overlap(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:]) else []


def _unclutter(fig) -> None:
    """Where two x tick labels of an axis would overlap (long condition names under narrow bars),
    break each label after its hyphens and at its spaces; where they still overlap, turn them
    upright."""
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        if not _crowded(ax, renderer):
            continue
        locs, texts = ax.get_xticks(), [t.get_text() for t in ax.get_xticklabels()]
        ax.set_xticks(locs, [t.replace("-", "-\n").replace(" ", "\n") for t in texts])
        fig.tight_layout()
        if _crowded(ax, renderer):
            ax.set_xticks(locs, texts)
            ax.tick_params(axis="x", labelrotation=90)


@timed
def save(fig, path: str | Path) -> Path:
    plt = pyplot()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    _unclutter(fig)
    fig.tight_layout()
    # the layout is done: without an engine left on the figure, savefig renders it once (a
    # figure's placeholder engine makes it render a throw-away image first)
    fig.set_layout_engine(None)
    save_figure(fig, path, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return path
