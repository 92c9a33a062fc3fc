"""TensorBoard logging of scalars and of map activity as images (or nothing, ``logger=none``).

The Scalars tab holds curves only: a tag's first point is held back until a second one comes, and
the tags that never get a second (a block's final state, a test's figure) go into one text
summary, ``summary/single_values``, when the run closes. The headline figures of a run are
HParams metrics (the scalars TensorBoard's HParams view needs, under ``values/``, a group that
sorts after the curves' ``train/`` and ``success/``, so the Scalars tab opens on a curve) and the
text summary ``summary/headline``."""
from __future__ import annotations

import functools
import math
import threading
import time
from pathlib import Path

import numpy as np
import torch


MIN_SIDE = 96  # pixels: small maps are enlarged (nearest neighbour) to at least this on their longer side
METRICS = "values"  # the group of the HParams metrics' one-point scalars (after every curve's group)
COLOUR_MAP = "viridis"  # of the map images and the figures' map panels (analysis.figures)
STRIP = 12  # pixels: the height of a 1-D map's strip, and each unit's width at least


def own_range(activity) -> np.ndarray:
    """A map scaled to [0, 1] by its own range, in float64: the one colour scale of the TensorBoard
    images and the figures' map panels. A map whose range is below a millionth of its largest
    magnitude is constant: all 0 when it is zero, else all 1 (every unit equally active), so a
    saturated map (PMCd at its threshold) looks the same in both."""
    a = np.asarray(activity.detach().cpu().double() if isinstance(activity, torch.Tensor) else activity, dtype=float)
    if a.size == 0:
        return a
    lo, hi, top = a.min(), a.max(), np.abs(a).max()
    if hi - lo <= 1e-6 * top or top == 0:
        return np.full_like(a, 1.0 if top > 0 else 0.0)
    return (a - lo) / (hi - lo)


def _to_image(activity: torch.Tensor) -> torch.Tensor:
    """A 1-D or 2-D map -> ``(3, H, W)`` RGB image: each map scaled by its own range
    (:func:`own_range`) and coloured by the figures' colour map (``COLOUR_MAP``), so a map looks
    the same in TensorBoard and in the figures, and an active unit never blends into the page. A
    1-D map becomes a strip of ``STRIP``-pixel cells, one per unit; a small 2-D map is enlarged by
    an integer factor, so every unit stays a visible square."""
    a = own_range(activity)
    if a.ndim == 1:
        a = a[None, :]
    h, w = a.shape
    k = max(1, math.ceil(MIN_SIDE / max(h, w)))
    if activity.dim() == 1:
        k = max(k, STRIP)
    a = a.repeat(k, 0).repeat(k, 1)
    if activity.dim() == 1 and a.shape[0] > STRIP:
        a = a[:STRIP]
    import matplotlib

    rgb = matplotlib.colormaps[COLOUR_MAP](a)[..., :3]
    return torch.as_tensor(rgb, dtype=torch.float32).permute(2, 0, 1).contiguous()


def _hparam_value(v):
    """A setting as TensorBoard's HParams view takes it: a number, a string or a boolean."""
    if isinstance(v, (bool, int, float, str)):
        return v
    return "none" if v is None else str(v)


def _markdown_table(header: list[str], rows: list[list[str]]) -> str:
    esc = lambda x: str(x).replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(map(esc, header)) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(map(esc, r)) + " |" for r in rows])


class NullLogger:
    """Accepts every call and writes nothing."""

    writes = False  # whether anything is written (a run sends the blocks' training curves only then)

    def scalar(self, tag: str, value: float, step: int = 0) -> None:
        pass

    def scalars(self, values: dict, step: int = 0, prefix: str = "") -> None:
        pass

    def map(self, tag: str, activity: torch.Tensor, step: int = 0) -> None:
        pass

    def maps(self, maps: dict, step: int = 0, prefix: str = "") -> None:
        pass

    def image(self, tag: str, rgb, step: int = 0) -> None:
        pass

    def text(self, tag: str, text: str, step: int = 0) -> None:
        pass

    def hparams(self, settings: dict, metrics: dict) -> None:
        pass

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


def _quiet_writer_thread() -> None:
    """TensorBoard's writer thread re-raises a failed write (a full disk) after handing it to the
    writer, whose next call raises it in the run's own thread: its traceback is not printed (the
    hook in place is wrapped once; other threads' errors go to it as before)."""
    previous = threading.excepthook
    if getattr(previous, "quiet_tensorboard", False):
        return

    def hook(args) -> None:
        if type(args.thread).__name__ == "_AsyncWriterThread" and isinstance(args.exc_value, OSError):
            return
        previous(args)

    hook.quiet_tensorboard = True
    threading.excepthook = hook


def _naming(method):
    """A failed write of TensorBoard's as an ``OSError`` that names the event file."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except OSError as err:
            if self.failed:  # said once; later calls (close) add nothing
                return None
            self.failed = True
            raise OSError(err.errno, err.strerror or str(err), str(self.event_file)) from None

    return wrapper


class TensorBoardLogger(NullLogger):
    """Writes TensorBoard events under ``root`` (``DIR/tb`` of a run): one event file per run, so a
    run rewritten into its directory replaces the old file instead of adding a second one. A write
    that fails (a full disk) is an ``OSError`` naming the event file, raised once."""

    writes = True

    def __init__(self, root: str | Path, map_images: bool = True) -> None:
        from torch.utils.tensorboard import SummaryWriter

        _quiet_writer_thread()
        root = Path(root)
        for old in root.glob("events.out.tfevents.*"):
            old.unlink()
        self.failed = False
        try:
            self.writer = SummaryWriter(log_dir=str(root))
            self.event_file = Path(self.writer._get_file_writer().event_writer._file_name)
        except OSError as err:
            made = sorted(root.glob("events.out.tfevents.*"))
            raise OSError(err.errno, f"{err.strerror or err} (TensorBoard's event file)",
                          str(made[-1] if made else root)) from None
        self.map_images = map_images
        self._first: dict[str, tuple[float, int, float]] = {}  # tag -> its one point so far (value, step, time)
        self._curves: set[str] = set()  # tags with two points or more, written as they come

    @_naming
    def scalar(self, tag: str, value: float, step: int = 0) -> None:
        """A point of the curve ``tag``; a tag's first point is written once a second one comes
        (a tag with one point ends in the text summary ``summary/single_values``)."""
        now = time.time()
        if tag in self._curves:
            self.writer.add_scalar(tag, float(value), step, walltime=now)
        elif tag in self._first:
            v0, s0, t0 = self._first.pop(tag)
            self.writer.add_scalar(tag, v0, s0, walltime=t0)
            self.writer.add_scalar(tag, float(value), step, walltime=now)
            self._curves.add(tag)
        else:
            self._first[tag] = (float(value), int(step), now)

    def scalars(self, values: dict, step: int = 0, prefix: str = "") -> None:
        for k, v in values.items():
            if isinstance(v, (int, float)):
                self.scalar(f"{prefix}{k}", v, step)

    @_naming
    def map(self, tag: str, activity: torch.Tensor, step: int = 0) -> None:
        if self.map_images:
            self.writer.add_image(tag, _to_image(activity), step, dataformats="CHW")

    def maps(self, maps: dict, step: int = 0, prefix: str = "") -> None:
        for k, v in maps.items():
            self.map(f"{prefix}{k}", v, step)

    @_naming
    def image(self, tag: str, rgb, step: int = 0) -> None:
        """An (H, W, 3) colour picture with values in [0, 1]."""
        if self.map_images:
            self.writer.add_image(tag, torch.as_tensor(rgb, dtype=torch.float32).clamp(0, 1), step, dataformats="HWC")

    @_naming
    def text(self, tag: str, text: str, step: int = 0) -> None:
        self.writer.add_text(tag, text, step)

    @_naming
    def hparams(self, settings: dict, metrics: dict) -> None:
        """The run's settings and headline figures in TensorBoard's HParams view, written into this
        run's event file (``SummaryWriter.add_hparams`` would open a second one)."""
        from torch.utils.tensorboard.summary import hparams

        metrics = {f"{METRICS}/{k}": float(v) for k, v in metrics.items() if isinstance(v, (int, float))}
        exp, ssi, sei = hparams({k: _hparam_value(v) for k, v in settings.items()}, metrics)
        fw = self.writer._get_file_writer()
        for summary in (exp, ssi, sei):
            fw.add_summary(summary)
        for k, v in metrics.items():
            self.writer.add_scalar(k, v, 0)
        if metrics:
            self.writer.add_text("summary/headline", _markdown_table(
                ["figure", "value"], [[k.removeprefix(f"{METRICS}/"), f"{v:.4g}"] for k, v in metrics.items()]), 0)

    @_naming
    def flush(self) -> None:
        self.writer.flush()

    @_naming
    def close(self) -> None:
        if self._first:
            rows = [[tag, f"{v:.4g}", str(step)] for tag, (v, step, _) in sorted(self._first.items())]
            self.writer.add_text("summary/single_values", "Figures logged once (a block's final state, a "
                                 "test's result): values, not curves.\n\n" + _markdown_table(["tag", "value", "step"], rows), 0)
            self._first.clear()
        self.writer.close()


def make_logger(cfg, root: str | Path):
    """Logger of a run from ``cfg.logger``."""
    if cfg.logger.kind == "none":
        return NullLogger()
    return TensorBoardLogger(root, cfg.logger.map_images)
