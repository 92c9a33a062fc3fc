"""TensorBoard logging of scalars and of map activity as images (or nothing, ``logger=none``)."""
from __future__ import annotations

from pathlib import Path

import torch


def _to_image(activity: torch.Tensor) -> torch.Tensor:
    """A 1-D or 2-D map -> ``(1, H, W)`` image in [0, 1] (each map scaled by its own range)."""
    a = activity.detach().float()
    if a.dim() == 1:
        a = a.unsqueeze(0)
    a = a - a.min()
    m = a.max()
    return (a / m if m > 0 else a).unsqueeze(0)


class NullLogger:
    """Accepts every call and writes nothing."""

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

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class TensorBoardLogger(NullLogger):
    """Writes TensorBoard events under ``root`` (``DIR/tb`` of a run)."""

    def __init__(self, root: str | Path, map_images: bool = True) -> None:
        from torch.utils.tensorboard import SummaryWriter

        self.writer = SummaryWriter(log_dir=str(root))
        self.map_images = map_images

    def scalar(self, tag: str, value: float, step: int = 0) -> None:
        self.writer.add_scalar(tag, float(value), step)

    def scalars(self, values: dict, step: int = 0, prefix: str = "") -> None:
        for k, v in values.items():
            if isinstance(v, (int, float)):
                self.scalar(f"{prefix}{k}", v, step)

    def map(self, tag: str, activity: torch.Tensor, step: int = 0) -> None:
        if self.map_images:
            self.writer.add_image(tag, _to_image(activity), step, dataformats="CHW")

    def maps(self, maps: dict, step: int = 0, prefix: str = "") -> None:
        for k, v in maps.items():
            self.map(f"{prefix}{k}", v, step)

    def image(self, tag: str, rgb, step: int = 0) -> None:
        """An (H, W, 3) colour picture with values in [0, 1]."""
        if self.map_images:
            self.writer.add_image(tag, torch.as_tensor(rgb, dtype=torch.float32).clamp(0, 1), step, dataformats="HWC")

    def text(self, tag: str, text: str, step: int = 0) -> None:
        self.writer.add_text(tag, text, step)

    def flush(self) -> None:
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


def make_logger(cfg, root: str | Path):
    """Logger of a run from ``cfg.logger``."""
    if cfg.logger.kind == "none":
        return NullLogger()
    return TensorBoardLogger(root, cfg.logger.map_images)
