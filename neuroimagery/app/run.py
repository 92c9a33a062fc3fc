"""Run directories (the layout described in docs/results.md) and the train / evaluate entry points.

``train(cfg)`` and ``evaluate(cfg)`` are plain functions; ``train.py`` and ``evaluate.py`` only
wrap them with ``@hydra.main``. Tests call them directly with a composed config.
"""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf

from ..core import console, manifest as mf, memory, progress
from ..config import Config
from ..nn import monitor
from ..nn.functional import intra_op_threads
from ..core.threads import auto_threads
from ..core.errors import UserInputError
from ..core.checkpoints import load_model, read_json, verify_run
from ..core.files import remove_stale_temporaries, torch_save, write_atomic
from ..core.lock import RunLock
from ..core.logger import NullLogger, make_logger
from ..validation import prepare

_STARTUP_TAKEN = []  # the first run of a process records its startup; later runs of a sweep have none


def process_age_s() -> float | None:
    """Seconds since this process started (Linux: from ``/proc``; None elsewhere): in a run's
    ``runtime_s`` the startup, i.e. the interpreter, the imports (the experiment's protocol
    included), composing the configuration and the checks before work."""
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

    With a ``manifest``, making a ``RunDir`` claims the directory: it takes the directory's lock
    (neuroimagery/core/lock.py), removes the temporary files a killed run left, refuses a directory that
    holds another run (unless ``overwrite``), then writes ``manifest.json`` with ``state: running``.
    A refusal leaves nothing: a directory this made is removed again. :meth:`close` records
    ``complete`` (with the hashes of the files written) or ``interrupted`` and releases the lock.
    """

    def __init__(self, root: str | Path, cfg: Config, raw: DictConfig | None = None,
                 manifest: dict | None = None) -> None:
        self.root = Path(root)
        self.cfg = cfg
        self.manifest = manifest
        self.timings: dict[str, float] = {}
        self.phase, self.trained, self.lock = "setup", False, None
        self.logger = NullLogger()
        created = not self.root.exists()
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise UserInputError(f"cannot create the run directory {self.root}: {err.strerror or err}") from None
        if manifest is not None:
            self._claim(manifest, getattr(cfg, "overwrite", False), created)
        try:
            for d in (self.checkpoints, self.figures):
                d.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            if self.lock is not None:
                self.lock.release()
            raise UserInputError(f"cannot create the run directory {self.root}: {err.strerror or err}") from None
        console.claimed(self.root)  # the job log may now be written here
        if manifest is not None:
            self._write_state("running")
        try:
            if raw is not None:  # Hydra's record, written once the directory is ours (hydra.output_subdir is null)
                hydra_dir = self.root / ".hydra"
                hydra_dir.mkdir(exist_ok=True)
                self._atomic(hydra_dir / "config.yaml", lambda p: p.write_text(OmegaConf.to_yaml(raw, resolve=True)))
                overrides = _hydra_overrides()
                if overrides is not None:
                    self._atomic(hydra_dir / "overrides.yaml", lambda p: p.write_text(OmegaConf.to_yaml(overrides)))
            self.logger = make_logger(cfg, self.tb)
        except BaseException as err:
            self.close(ok=False, stopped=stopped_by(err, "starting"))
            raise

    def _claim(self, manifest: dict, overwrite: bool, created: bool) -> None:
        """Take the directory's lock and check that it holds no other run (first without writing
        anything, so that a refused run leaves another run's directory as it was)."""
        self.lock = RunLock(self.root)
        try:
            self.lock.check()
            self._check_claim(manifest, overwrite, notes=False)
            try:
                self.lock.acquire()
            except OSError as err:  # a directory that exists but cannot be written
                raise UserInputError(f"cannot write into the run directory {self.root}: "
                                     f"{err.strerror or err}") from None
            gone = remove_stale_temporaries(self.root)
            if gone:
                console.note(f"removed {len(gone)} temporary file(s) that a killed run left in {self.root} "
                             f"({', '.join(p.name for p in gone[:3])}{', ...' if len(gone) > 3 else ''})")
            self._check_claim(manifest, overwrite)
        except BaseException:
            self.lock.release()
            if created:
                _remove_empty_tree(self.root)
            raise

    def _check_claim(self, manifest: dict, overwrite: bool, notes: bool = True) -> None:
        """Refuse a directory that holds another run (unless ``overwrite``); ``notes``: say what
        is kept or replaced."""
        path = self.root / "manifest.json"
        held = [n for n in RUN_FILES if (self.root / n).exists()] + sorted(p.name for p in self.checkpoints.glob("*.pt"))
        if held and not overwrite:
            if not path.exists():
                raise UserInputError(f"{self.root} already holds a run without a manifest ({', '.join(held[:3])}; a "
                                     "run of version 0.1.0, before runs had manifests, or not a run): choose another "
                                     "directory or set overwrite=true")
            old = read_json(path, "run manifest")
            if held == ["manifest.json"] and old.get("state") in ("running", "interrupted"):
                if notes:
                    console.note(f"{self.root} holds a run that stopped before it wrote any result "
                                 f"({old.get('stopped') or 'killed'}): replacing it")
                return
            diff = mf.differences(manifest["settings"], old.get("settings", {}))
            if old.get("experiment") != manifest["experiment"]:
                diff.insert(0, f"experiment {old.get('experiment')!r} (stored) vs {manifest['experiment']!r} (this run)")
            if diff:
                raise UserInputError(f"{self.root} holds another run ({'; '.join(diff[:4])}"
                                     f"{'; ...' if len(diff) > 4 else ''}): choose another directory or set overwrite=true")
            if not notes:
                return
            if old.get("package") != manifest["package"]:
                console.note(f"{self.root} holds a run of version {old.get('package')} (this is {manifest['package']})")
            console.note(f"{self.root} holds a run with the same settings: "
                         + ("finished tasks are kept and the run resumes" if manifest["experiment"] == "exp5" else "rewriting it"))

    def _write_state(self, state: str, stopped: str | None = None) -> None:
        """``manifest.json``: the manifest with the run's ``state`` (neuroimagery/core/manifest.py)."""
        data = {**self.manifest, "state": state, "trained": self.trained}
        if stopped:
            data["stopped"] = stopped
        if state == "complete" or self.trained:
            data["files"] = mf.output_hashes(self.root)
        self.write_json("manifest.json", data)

    def mark_trained(self) -> None:
        """Training finished and its checkpoints are whole: ``checkpoint=`` may use them."""
        self.trained = True
        if self.manifest is not None and self.lock is not None and self.lock.held:
            self._write_state("running")

    def _atomic(self, path: Path, write) -> Path:
        """``write(tmp)`` then rename onto ``path``; an ``OSError`` leaves no temporary file behind and
        becomes a :class:`UserInputError` naming ``path``."""
        try:
            return write_atomic(path, write)
        except OSError as err:
            model = ""
            if self.trained and path.parent != self.checkpoints and path.name != "manifest.json":
                model = f"; the trained model is whole in {self.checkpoints}"
            raise UserInputError(f"cannot write {path}: {err.strerror or err}{model}{self._rescue(path, write)}") from None

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

    def close(self, ok: bool = True, stopped: str | None = None) -> None:
        """Close the logger, record ``complete`` (``ok``) or ``interrupted`` and release the lock.
        A failure to write while finishing a good run is raised (the run is then ``interrupted``);
        while an error is already on its way up, it is not (that error is the one to show)."""
        pending = None
        try:
            self.logger.close()
        except OSError as err:
            if ok:
                pending, ok = err, False
                stopped = f"cannot write {err.filename or self.tb}: {err.strerror or err}"
        self.logger = NullLogger()
        if self.lock is not None and self.lock.held:
            try:
                self._write_state("complete" if ok else "interrupted", None if ok else stopped)
            except (OSError, UserInputError) as err:
                pending = pending or (err if ok else None)
            finally:
                self.lock.release()
        if pending is not None:
            raise pending


def _remove_empty_tree(root: Path) -> None:
    """Remove ``root`` if it holds nothing but empty folders (a refused run's own directory)."""
    try:
        for d in sorted((p for p in root.rglob("*")), key=lambda p: len(p.parts), reverse=True):
            if not d.is_dir() or d.is_symlink():
                return
            d.rmdir()
        root.rmdir()
    except OSError:
        pass


def stopped_by(err: BaseException | None, phase: str) -> str:
    """How a run stopped, for ``manifest.json``'s ``stopped``."""
    if isinstance(err, KeyboardInterrupt):
        return f"interrupted (Ctrl-C or SIGTERM) while {phase}"
    if err is None:
        return f"stopped while {phase}"
    first = (str(err).strip().splitlines() or [type(err).__name__])[0]
    return f"stopped by an error while {phase}: {first[:200]}"


def _output_dir(out_dir: str | Path | None) -> Path:
    if out_dir is not None:
        return Path(out_dir)
    try:
        from hydra.core.hydra_config import HydraConfig

        return Path(HydraConfig.get().runtime.output_dir)
    except Exception:
        return Path("outputs") / time.strftime("%Y-%m-%d_%H-%M-%S")


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


def _prepare(cfg: DictConfig | Config, checkpoint: bool = False, checked: tuple | None = None):
    """Validate everything (config, stimulus folder, the checkpoint named) before any work; ``checked``:
    what :func:`~neuroimagery.validation.prepare` returned for ``cfg``, if it ran already. The run
    directory is claimed later, by :class:`RunDir`, when work starts."""
    raw = cfg if isinstance(cfg, DictConfig) else None
    conf, module = checked if checked is not None else prepare(cfg)
    manifest = mf.build(conf, module)
    if conf.checkpoint and not checkpoint:
        raise UserInputError("checkpoint= has no effect in training: it names a trained run for evaluate.py")
    if checkpoint and conf.checkpoint:
        verify_run(conf.checkpoint, module.checkpoints, manifest)
    return conf, module, manifest, raw


@contextlib.contextmanager
def _recorded(run: RunDir):
    """Close ``run`` on the way out: ``complete`` if the body finished, else ``interrupted`` with
    how it stopped."""
    try:
        yield
    except BaseException as err:
        run.close(ok=False, stopped=stopped_by(err, run.phase))
        if isinstance(err, OSError) and run.trained:  # a full disk while testing: say where the model is
            raise UserInputError(f"cannot write {err.filename or run.root}: {err.strerror or err}; the trained model is "
                                 f"whole in {run.checkpoints}") from None
        raise
    run.close(ok=True)


def _train_phase(conf, module, run) -> tuple[Any, dict]:
    t0 = time.perf_counter()
    memory.reset_peak()
    run.phase = "training"
    # the blocks' training curves (neuroimagery.nn.monitor) go to the logger as scalars; with nothing
    # written, no reader is installed and the blocks measure nothing
    curves = monitor.to(run.logger.scalar) if run.logger.writes else contextlib.nullcontext()
    with progress.phase(f"{conf.experiment.name} train", conf.progress), curves:
        trained = module.train(conf, run)
    run.timings["train"] = round(time.perf_counter() - t0, 3)
    run.mark_trained()
    return trained, {"train": memory.peak_rss_mb()}


def train(cfg: DictConfig | Config, out_dir: str | Path | None = None, checked: tuple | None = None) -> dict:
    """Train experiment ``cfg.experiment.name`` and save its checkpoints. Returns a small summary.
    ``checked``: :func:`~neuroimagery.validation.prepare`'s answer for ``cfg``, when it ran already."""
    conf, module, manifest, raw = _prepare(cfg, checked=checked)
    module.import_phases()  # before the training's clock starts
    with intra_op_threads(conf.threads or auto_threads()):  # restored afterwards
        run = RunDir(_output_dir(out_dir), conf, raw, manifest)
        with _recorded(run):
            _, peaks = _train_phase(conf, module, run)
            # experiments whose simulated subjects are not cfg.participants say how many they trained
            count, unit = module.trained_count(conf) if module.trained_count else (conf.participants, "participants")
            info = {"experiment": conf.experiment.name, "participants": count, "unit": unit, "runtime_s": dict(run.timings),
                    "peak_rss_mb": peaks, "checkpoints": str(run.checkpoints)}
            run.phase = "writing train.json"
            run.write_json("train.json", info)
        return info


def evaluate(cfg: DictConfig | Config, out_dir: str | Path | None = None, checked: tuple | None = None) -> dict:
    """Test experiment ``cfg.experiment.name``; trains first unless ``cfg.checkpoint`` names a run.
    ``checked``: :func:`~neuroimagery.validation.prepare`'s answer for ``cfg``, when it ran already.

    Writes ``trials.csv`` / ``individuals.csv``, ``summary.json``, ``report.md``, ``figures/``, ``tb/``.
    """
    first = not _STARTUP_TAKEN
    _STARTUP_TAKEN.append(True)
    conf, module, manifest, raw = _prepare(cfg, checkpoint=True, checked=checked)
    module.import_phases()  # part of the startup, not of the training's time
    started = process_age_s() if first else None
    with intra_op_threads(conf.threads or auto_threads()):  # restored afterwards
        trained = load_model(module, conf, conf.checkpoint) if conf.checkpoint else None  # before any claim
        run = RunDir(_output_dir(out_dir), conf, raw, manifest)
        if started is not None:
            run.timings["startup"] = round(started, 3)
        with _recorded(run):
            if conf.checkpoint:
                ck = Path(conf.checkpoint)
                tj = ck / "train.json"
                peaks = {}
                if tj.exists():
                    record = read_json(tj, "training record")
                    run.timings.update(record.get("runtime_s", {}))
                    peaks.update(record.get("peak_rss_mb", {}))
            else:
                trained, peaks = _train_phase(conf, module, run)
            from ..analysis import figures

            t0, drawn = time.perf_counter(), figures.drawing_time()
            memory.reset_peak()
            run.phase = "testing"
            with progress.phase(f"{conf.experiment.name} test", conf.progress):
                summary = module.evaluate(conf, run, trained)
            run.timings["evaluate"] = round(time.perf_counter() - t0, 3)
            run.timings["figures"] = round(figures.drawing_time() - drawn, 3)  # part of evaluate
            peaks["evaluate"] = memory.peak_rss_mb()
            trials = run.root / "trials.csv"
            if "stimuli" in module.inputs and trials.is_file():  # a user's stimuli against chance
                import pandas as pd

                from ..analysis.summary import custom_vs_chance

                chance = custom_vs_chance(pd.read_csv(trials))
                if chance is not None:
                    summary["custom_vs_chance"] = chance
            summary["runtime_s"] = dict(run.timings)
            summary["peak_rss_mb"] = peaks  # this process's peak resident memory per phase (neuroimagery/core/memory.py)
            run.phase = "writing the summary and report"
            run.write_json("summary.json", summary)
            from ..analysis.summary import headline

            settings = run.manifest["settings"] if run.manifest else mf.flatten(conf)
            run.logger.hparams(mf.as_used(settings, conf.experiment.name), headline(summary))
            if module.report is not None:
                module.report(conf, run, summary)
        return summary
