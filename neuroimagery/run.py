"""Run directories (the layout described in docs/results.md) and the train / evaluate entry points.

``train(cfg)`` and ``evaluate(cfg)`` are plain functions; ``train.py`` and ``evaluate.py`` only
wrap them with ``@hydra.main``. Tests call them directly with a composed config.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf

from .config import Config, experiment_module, validate
from .errors import UserInputError
from .logger import make_logger


class RunDir:
    """Files a run leaves behind (see docs/results.md).

    ``root/.hydra/config.yaml``, ``checkpoints/``, ``train.json`` (train.py), ``trials.csv`` or
    ``individuals.csv``, ``summary.json``, ``report.md``, ``figures/*.png``, ``tb/``.
    """

    def __init__(self, root: str | Path, cfg: Config, raw: DictConfig | None = None) -> None:
        self.root = Path(root)
        self.cfg = cfg
        for d in (self.root, self.checkpoints, self.figures):
            d.mkdir(parents=True, exist_ok=True)
        hydra_cfg = self.root / ".hydra" / "config.yaml"
        if raw is not None and not hydra_cfg.exists():
            hydra_cfg.parent.mkdir(parents=True, exist_ok=True)
            hydra_cfg.write_text(OmegaConf.to_yaml(raw, resolve=True))
        self.logger = make_logger(cfg, self.tb)
        self.timings: dict[str, float] = {}

    checkpoints = property(lambda self: self.root / "checkpoints")
    figures = property(lambda self: self.root / "figures")
    tb = property(lambda self: self.root / "tb")
    summary_path = property(lambda self: self.root / "summary.json")
    report_path = property(lambda self: self.root / "report.md")

    def save_checkpoint(self, name: str, state: dict) -> Path:
        """``torch.save`` into ``checkpoints/<name>.pt`` atomically (write, then rename)."""
        path = self.checkpoints / f"{name}.pt"
        tmp = path.with_suffix(".pt.tmp")
        torch.save(state, tmp)
        os.replace(tmp, path)
        return path

    def write_json(self, name: str, data: Any) -> Path:
        path = self.root / name
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False, default=_json_default) + "\n")
        os.replace(tmp, path)
        return path

    def write_csv(self, name: str, frame) -> Path:
        path = self.root / name
        tmp = path.with_suffix(path.suffix + ".tmp")
        frame.to_csv(tmp, index=False, float_format="%.6g")
        os.replace(tmp, path)
        return path

    def close(self) -> None:
        self.logger.close()


def _json_default(o):
    if isinstance(o, torch.Tensor):
        return o.tolist()
    if hasattr(o, "item"):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def load_checkpoint(checkpoint: str | Path, name: str) -> dict:
    """Read ``checkpoints/<name>.pt`` of a training run's directory, with a clear error if absent."""
    path = Path(checkpoint) / "checkpoints" / f"{name}.pt"
    if not path.exists():
        raise UserInputError(f"checkpoint: no {path} (is {checkpoint} the directory of a training run of this experiment?)")
    return torch.load(path, map_location="cpu", weights_only=False)


def _output_dir(out_dir: str | Path | None) -> Path:
    if out_dir is not None:
        return Path(out_dir)
    try:
        from hydra.core.hydra_config import HydraConfig

        return Path(HydraConfig.get().runtime.output_dir)
    except Exception:
        return Path("outputs") / time.strftime("%Y-%m-%d_%H-%M-%S")


def _prepare(cfg: DictConfig | Config, out_dir):
    raw = cfg if isinstance(cfg, DictConfig) else None
    conf = validate(cfg)
    if conf.threads:
        torch.set_num_threads(conf.threads)
    module = experiment_module(conf.experiment.name)
    run = RunDir(_output_dir(out_dir), conf, raw)
    return conf, module, run


def _check_checkpoint(conf: Config) -> Path:
    ck = Path(conf.checkpoint)
    if not ck.is_dir():
        raise UserInputError(f"checkpoint: {ck} is not a directory")
    saved = ck / ".hydra" / "config.yaml"
    if saved.exists():
        name = OmegaConf.load(saved).get("experiment", {}).get("name")
        if name is not None and name != conf.experiment.name:
            raise UserInputError(f"checkpoint: {ck} was trained for {name}, not {conf.experiment.name}")
    return ck


def train(cfg: DictConfig | Config, out_dir: str | Path | None = None) -> dict:
    """Train experiment ``cfg.experiment.name`` and save its checkpoints. Returns a small summary."""
    conf, module, run = _prepare(cfg, out_dir)
    try:
        t0 = time.perf_counter()
        module.train(conf, run)
        run.timings["train"] = round(time.perf_counter() - t0, 3)
        # experiments whose simulated subjects are not cfg.participants say how many they trained
        count, unit = module.trained_count(conf) if hasattr(module, "trained_count") else (conf.participants, "participants")
        info = {"experiment": conf.experiment.name, "participants": count, "unit": unit, "runtime_s": dict(run.timings),
                "checkpoints": str(run.checkpoints)}
        run.write_json("train.json", info)
        return info
    finally:
        run.close()


def evaluate(cfg: DictConfig | Config, out_dir: str | Path | None = None) -> dict:
    """Test experiment ``cfg.experiment.name``; trains first unless ``cfg.checkpoint`` names a run.

    Writes ``trials.csv`` / ``individuals.csv``, ``summary.json``, ``report.md``, ``figures/``, ``tb/``.
    """
    conf, module, run = _prepare(cfg, out_dir)
    try:
        if conf.checkpoint:
            ck = _check_checkpoint(conf)
            trained = module.load(conf, ck)
            tj = ck / "train.json"
            if tj.exists():
                run.timings.update(json.loads(tj.read_text()).get("runtime_s", {}))
        else:
            t0 = time.perf_counter()
            trained = module.train(conf, run)
            run.timings["train"] = round(time.perf_counter() - t0, 3)
        t0 = time.perf_counter()
        summary = module.evaluate(conf, run, trained)
        run.timings["evaluate"] = round(time.perf_counter() - t0, 3)
        summary["runtime_s"] = dict(run.timings)
        run.write_json("summary.json", summary)
        if hasattr(module, "report"):
            module.report(conf, run, summary)
        return summary
    finally:
        run.close()
