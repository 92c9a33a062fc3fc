"""Run directories (the layout described in docs/results.md) and the train / evaluate entry points.

``train(cfg)`` and ``evaluate(cfg)`` are plain functions; ``train.py`` and ``evaluate.py`` only
wrap them with ``@hydra.main``. Tests call them directly with a composed config.
"""
from __future__ import annotations

import json
import os
import pickle
import tempfile
import time
import zipfile
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf

from . import console, manifest as mf, memory, progress
from .config import Config, experiment_module, validate
from .nn.functional import intra_op_threads
from .threads import auto_threads
from .errors import UserInputError
from .files import torch_save, write_atomic
from .logger import make_logger
from .validation import check_run

_STARTUP_TAKEN = []  # the first run of a process records its startup; later runs of a sweep have none


def process_age_s() -> float | None:
    """Seconds since this process started (Linux: from ``/proc``; None elsewhere): in a run's
    ``runtime_s`` the startup, i.e. the interpreter, the imports and composing the configuration."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return None


# files whose presence means a directory already holds a run
RUN_FILES = ("manifest.json", "train.json", "summary.json", "trials.csv", "individuals.csv", "report.md")


class RunDir:
    """Files a run leaves behind (see docs/results.md).

    ``root/.hydra/config.yaml``, ``checkpoints/``, ``train.json`` (train.py), ``trials.csv`` or
    ``individuals.csv``, ``summary.json``, ``report.md``, ``figures/*.png``, ``tb/``.
    """

    def __init__(self, root: str | Path, cfg: Config, raw: DictConfig | None = None,
                 manifest: dict | None = None) -> None:
        self.root = Path(root)
        self.cfg = cfg
        self.manifest = manifest
        try:
            for d in (self.root, self.checkpoints, self.figures):
                d.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise UserInputError(f"cannot create the run directory {self.root}: {err.strerror or err}") from None
        if manifest is not None:
            self._claim(manifest, getattr(cfg, "overwrite", False))
        if raw is not None:  # Hydra's record, written once the directory is ours (hydra.output_subdir is null)
            hydra_dir = self.root / ".hydra"
            hydra_dir.mkdir(exist_ok=True)
            self._atomic(hydra_dir / "config.yaml", lambda p: p.write_text(OmegaConf.to_yaml(raw, resolve=True)))
            overrides = _hydra_overrides()
            if overrides is not None:
                self._atomic(hydra_dir / "overrides.yaml", lambda p: p.write_text(OmegaConf.to_yaml(overrides)))
        self.logger = make_logger(cfg, self.tb)
        self.timings: dict[str, float] = {}

    def _claim(self, manifest: dict, overwrite: bool) -> None:
        """Refuse a directory that holds another run (unless ``overwrite``), then write our manifest."""
        path = self.root / "manifest.json"
        held = [n for n in RUN_FILES if (self.root / n).exists()] + sorted(p.name for p in self.checkpoints.glob("*.pt"))
        if held and not overwrite:
            if not path.exists():
                raise UserInputError(f"{self.root} already holds a run without a manifest ({', '.join(held[:3])}; a "
                                     "run of version 0.1.0, before runs had manifests, or not a run): choose another "
                                     "directory or set overwrite=true")
            old = read_json(path, "run manifest")
            diff = mf.differences(manifest["settings"], old.get("settings", {}))
            if old.get("experiment") != manifest["experiment"]:
                diff.insert(0, f"experiment {old.get('experiment')!r} (stored) vs {manifest['experiment']!r} (this run)")
            if diff:
                raise UserInputError(f"{self.root} holds another run ({'; '.join(diff[:4])}"
                                     f"{'; ...' if len(diff) > 4 else ''}): choose another directory or set overwrite=true")
            if old.get("package") != manifest["package"]:
                console.note(f"{self.root} holds a run of version {old.get('package')} (this is {manifest['package']})")
            console.note(f"{self.root} holds a run with the same settings: "
                         + ("finished tasks are kept and the run resumes" if manifest["experiment"] == "exp5" else "rewriting it"))
        self.write_json("manifest.json", manifest)

    def _atomic(self, path: Path, write) -> Path:
        """``write(tmp)`` then rename onto ``path``; an ``OSError`` leaves no temporary file behind and
        becomes a :class:`UserInputError` naming ``path``."""
        try:
            return write_atomic(path, write)
        except OSError as err:
            raise UserInputError(f"cannot write {path}: {err.strerror or err}{self._rescue(path, write)}") from None

    @staticmethod
    def _rescue(path: Path, write) -> str:
        """Try to keep what could not be written in a temporary folder; say where (or that it failed)."""
        try:
            spare = Path(tempfile.mkdtemp(prefix="neuroimagery-")) / path.name
            write(spare)
            return f"; kept in {spare}"
        except Exception:  # the fallback is best effort: the error above is the one that matters
            return ""

    checkpoints = property(lambda self: self.root / "checkpoints")
    figures = property(lambda self: self.root / "figures")
    tb = property(lambda self: self.root / "tb")
    summary_path = property(lambda self: self.root / "summary.json")
    report_path = property(lambda self: self.root / "report.md")

    def save_checkpoint(self, name: str, state: dict) -> Path:
        """``torch.save`` into ``checkpoints/<name>.pt`` atomically (write, then rename), with the
        run's manifest and a hash of the stored tensors under ``"manifest"``."""
        if self.manifest is not None:
            state = {**state, "manifest": {**self.manifest, "tensor_hash": mf.tensor_hash(state)}}
        return self._atomic(self.checkpoints / f"{name}.pt", lambda p: torch_save(state, p))

    def write_json(self, name: str, data: Any) -> Path:
        text = json.dumps(data, indent=2, sort_keys=False, default=_json_default) + "\n"
        return self._atomic(self.root / name, lambda p: p.write_text(text))

    def write_csv(self, name: str, frame) -> Path:
        return self._atomic(self.root / name, lambda p: frame.to_csv(p, index=False, float_format="%.6g"))

    def close(self) -> None:
        self.logger.close()


def _hydra_overrides():
    try:
        from hydra.core.hydra_config import HydraConfig

        return list(HydraConfig.get().overrides.task)
    except Exception:  # not under @hydra.main
        return None


def _json_default(o):
    if isinstance(o, torch.Tensor):
        return o.tolist()
    if hasattr(o, "item"):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def read_json(path: Path, what: str) -> dict:
    """A JSON object from ``path``; a missing, unreadable or corrupt file is a :class:`UserInputError`."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise UserInputError(f"{what} {path}: cannot be read ({getattr(err, 'strerror', None) or err})") from None
    if not isinstance(data, dict):
        raise UserInputError(f"{what} {path}: not a JSON object")
    return data


def safe_load(path: str | Path) -> Any:
    """``torch.load`` with ``weights_only=True``: tensors and plain containers only, so nothing in
    the file is executed. A file that is not such a checkpoint is a :class:`UserInputError`."""
    path = Path(path)
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, zipfile.BadZipFile, ValueError, TypeError,
            AttributeError, ImportError, IndexError, KeyError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise UserInputError(f"checkpoint {path}: not a checkpoint this package wrote, or corrupt; "
                             f"nothing in it was run ({first[:200]})") from None
    except OSError as err:
        raise UserInputError(f"checkpoint {path}: cannot be read ({err.strerror or err})") from None


def _checkpoint_file(checkpoint: str | Path, name: str, experiment: str) -> Path:
    path = Path(checkpoint) / "checkpoints" / f"{name}.pt"
    if not path.exists():
        raise UserInputError(f"checkpoint: no {path} (is {checkpoint} the directory of a training run of {experiment}?)")
    return path


def load_checkpoint(checkpoint: str | Path, name: str) -> dict:
    """Read ``checkpoints/<name>.pt`` of a training run's directory, with a clear error if absent."""
    path = _checkpoint_file(checkpoint, name, "this experiment")
    state = safe_load(path)
    if not isinstance(state, dict):
        raise UserInputError(f"checkpoint {path}: holds a {type(state).__name__}, not a checkpoint of this package")
    state.pop("manifest", None)
    return state


def verify_checkpoint(checkpoint: str | Path, name: str, manifest: dict) -> None:
    """Check ``checkpoints/<name>.pt`` against this run's ``manifest``: the tensors are those it
    stored (hash), and it was trained with the same settings; every differing key is named."""
    path = _checkpoint_file(checkpoint, name, manifest["experiment"])
    state = safe_load(path)
    stored = state.pop("manifest", None) if isinstance(state, dict) else None
    if not isinstance(stored, dict):
        raise UserInputError(f"checkpoint {path}: has no manifest (written by version 0.1.0, before checkpoints had "
                             "manifests, or not by this package): train it again with this version")
    if stored.get("tensor_hash") != mf.tensor_hash(state):
        raise UserInputError(f"checkpoint {path}: its tensors do not match the hash it stores (altered or corrupt)")
    if stored.get("experiment") != manifest["experiment"]:
        raise UserInputError(f"checkpoint: {checkpoint} was trained for {stored.get('experiment')}, "
                             f"not {manifest['experiment']}")
    diff = mf.differences(manifest["training"], stored.get("training", {}))
    if diff:
        raise UserInputError(f"checkpoint {path} was trained with other settings: {'; '.join(diff)} "
                             "(set them as in training, or train again)")
    if stored.get("package") != manifest["package"]:
        console.note(f"checkpoint {path} was written by version {stored.get('package')} (this is "
                     f"{manifest['package']})")


def _output_dir(out_dir: str | Path | None) -> Path:
    if out_dir is not None:
        return Path(out_dir)
    try:
        from hydra.core.hydra_config import HydraConfig

        return Path(HydraConfig.get().runtime.output_dir)
    except Exception:
        return Path("outputs") / time.strftime("%Y-%m-%d_%H-%M-%S")


def _prepare(cfg: DictConfig | Config, out_dir, checkpoint: bool = False):
    """Validate everything (config, stimulus folder, the checkpoint named) before any work, then
    claim the run directory."""
    raw = cfg if isinstance(cfg, DictConfig) else None
    conf = validate(cfg)
    module = experiment_module(conf.experiment.name)
    check_run(conf, module)
    manifest = mf.build(conf, module)
    if conf.checkpoint and not checkpoint:
        raise UserInputError("checkpoint= has no effect in training: it names a trained run for evaluate.py")
    if checkpoint and conf.checkpoint:
        ck = Path(conf.checkpoint)
        if not ck.is_dir():
            raise UserInputError(f"checkpoint: {ck} is not a directory")
        for name in getattr(module, "CHECKPOINTS", ("model",)):
            verify_checkpoint(ck, name, manifest)
    run = RunDir(_output_dir(out_dir), conf, raw, manifest)
    return conf, module, run


def train(cfg: DictConfig | Config, out_dir: str | Path | None = None) -> dict:
    """Train experiment ``cfg.experiment.name`` and save its checkpoints. Returns a small summary."""
    conf, module, run = _prepare(cfg, out_dir)
    with intra_op_threads(conf.threads or auto_threads()):  # restored afterwards
        try:
            t0 = time.perf_counter()
            memory.reset_peak()
            with progress.phase(f"{conf.experiment.name} train", conf.progress), run.logger.training_curves():
                module.train(conf, run)
            run.timings["train"] = round(time.perf_counter() - t0, 3)
            peaks = {"train": memory.peak_rss_mb()}
            # experiments whose simulated subjects are not cfg.participants say how many they trained
            count, unit = module.trained_count(conf) if hasattr(module, "trained_count") else (conf.participants, "participants")
            info = {"experiment": conf.experiment.name, "participants": count, "unit": unit, "runtime_s": dict(run.timings),
                    "peak_rss_mb": peaks, "checkpoints": str(run.checkpoints)}
            run.write_json("train.json", info)
            return info
        finally:
            run.close()


def evaluate(cfg: DictConfig | Config, out_dir: str | Path | None = None) -> dict:
    """Test experiment ``cfg.experiment.name``; trains first unless ``cfg.checkpoint`` names a run.

    Writes ``trials.csv`` / ``individuals.csv``, ``summary.json``, ``report.md``, ``figures/``, ``tb/``.
    """
    started = None if _STARTUP_TAKEN else process_age_s()
    _STARTUP_TAKEN.append(True)
    conf, module, run = _prepare(cfg, out_dir, checkpoint=True)
    if started is not None:
        run.timings["startup"] = round(started, 3)
    with intra_op_threads(conf.threads or auto_threads()):  # restored afterwards
        try:
            if conf.checkpoint:
                ck = Path(conf.checkpoint)
                trained = module.load(conf, ck)
                tj = ck / "train.json"
                peaks = {}
                if tj.exists():
                    record = read_json(tj, "training record")
                    run.timings.update(record.get("runtime_s", {}))
                    peaks.update(record.get("peak_rss_mb", {}))
            else:
                t0 = time.perf_counter()
                memory.reset_peak()
                with progress.phase(f"{conf.experiment.name} train", conf.progress), run.logger.training_curves():
                    trained = module.train(conf, run)
                run.timings["train"] = round(time.perf_counter() - t0, 3)
                peaks = {"train": memory.peak_rss_mb()}
            from .analysis import figures

            t0, drawn = time.perf_counter(), figures.drawing_time()
            memory.reset_peak()
            with progress.phase(f"{conf.experiment.name} test", conf.progress):
                summary = module.evaluate(conf, run, trained)
            run.timings["evaluate"] = round(time.perf_counter() - t0, 3)
            run.timings["figures"] = round(figures.drawing_time() - drawn, 3)  # part of evaluate
            peaks["evaluate"] = memory.peak_rss_mb()
            trials = run.root / "trials.csv"
            if "stimuli" in getattr(module, "INPUTS", ()) and trials.is_file():  # a user's stimuli against chance
                import pandas as pd

                from .analysis.summary import custom_vs_chance

                chance = custom_vs_chance(pd.read_csv(trials))
                if chance is not None:
                    summary["custom_vs_chance"] = chance
            summary["runtime_s"] = dict(run.timings)
            summary["peak_rss_mb"] = peaks  # this process's peak resident memory per phase (neuroimagery/memory.py)
            run.write_json("summary.json", summary)
            from .analysis.summary import headline

            run.logger.hparams(run.manifest["settings"] if run.manifest else mf.flatten(conf), headline(summary))
            if hasattr(module, "report"):
                module.report(conf, run, summary)
            return summary
        finally:
            run.close()
