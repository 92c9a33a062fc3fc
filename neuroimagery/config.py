"""Hydra structured-config schema of the whole project, and its validation.

``conf/config.yaml`` composes ``experiment/``, ``vision/``, ``stimuli/`` and ``logger/`` groups on
top of :class:`Config`. Every group is typed by a dataclass, so a misspelt key or a wrong type is
rejected by Hydra while composing; range checks run in each dataclass's ``__post_init__`` when
:func:`validate` turns the composed config into objects, before any work starts.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import re
import warnings
from pathlib import Path
from dataclasses import dataclass, field
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from .core.bounds import bounded, check_declared
from .core.errors import UserInputError
from .core.experiment import Experiment
from .core.manifest import flatten
from .vision.config import StimuliConfig, VisionConfig



def _experiment_names() -> tuple[str, ...]:
    """The experiments: every subpackage of ``neuroimagery/experiments`` whose ``__init__`` defines
    ``EXPERIMENT`` (read from the source, nothing imported), numbered ones first."""
    root = Path(__file__).parent / "experiments"
    names = [d.name for d in root.iterdir() if (d / "__init__.py").is_file()
             and re.search(r"^EXPERIMENT\s*=", (d / "__init__.py").read_text(), re.M)]
    return tuple(sorted(names, key=lambda n: (not re.fullmatch(r"exp\d+", n), len(n), n)))


EXPERIMENTS = _experiment_names()
# conf/hydra/launcher/submitit_*.yaml share their names with the launcher plugin's schemas, which
# Hydra 1.3 still checks them against, with a deprecation warning; they list every key and work
# without the schema too. Set on import: a sweep job of the submitit launcher composes its
# configuration again in a process of its own, after unpickling the task (which imports this module).
warnings.filterwarnings("ignore", message=r"\s*'hydra/launcher/submitit_\w+' is validated against ConfigStore schema")


@dataclass
class LoggerConfig:
    """TensorBoard output (``logger=tensorboard``) or none (``logger=none``)."""

    kind: str = bounded("tensorboard", choices=("tensorboard", "none"))
    map_images: bool = True  # write map activity as images
    sample_trials: int = bounded(2, ge=0, le=10_000)  # trials per test whose maps are logged step by step

    def __post_init__(self) -> None:
        check_declared(self, "logger.")


@dataclass
class Config:
    """Top-level configuration shared by every experiment."""

    experiment: Any = MISSING
    vision: VisionConfig = field(default_factory=VisionConfig)
    stimuli: StimuliConfig = field(default_factory=StimuliConfig)
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    # fixes every random draw of training and testing, except the eye's image noise (off by default),
    # which has its own seed, vision.seed, and is the same whatever this seed (see docs/stimuli.md)
    seed: int = bounded(0, ge=0, lt=2 ** 63)
    participants: int = bounded(10, ge=1)  # simulated participants (independent weights), trained as one batch
    # full protocol, or 'quick' for a first look (each experiment says what it shrinks)
    preset: str = bounded("full", choices=("full", "quick"))
    checkpoint: Optional[str] = None  # evaluate.py: a training run's directory; None trains first
    progress: bool = True  # progress bars on long loops
    # torch intra-op threads during the run (0 = the cores other work leaves free, neuroimagery.core.threads);
    # more than the cores this process may use is refused (neuroimagery.core.resources)
    threads: int = bounded(0, ge=0)
    overwrite: bool = False  # write into a run directory that holds a run with other settings
    # skip the checks of the memory a run needs and of threads against the cores (neuroimagery.core.resources),
    # for a machine whose limits are not visible to the process
    allow_large: bool = False

    def __post_init__(self) -> None:
        check_declared(self, "", recursive=False)


def experiment(name: str) -> Experiment:
    """The protocol of experiment ``name``: ``EXPERIMENT`` of ``neuroimagery.experiments.<name>``."""
    if name not in EXPERIMENTS:
        raise UserInputError(f"unknown experiment {name!r}; choose one of {', '.join(EXPERIMENTS)}")
    return importlib.import_module(f"neuroimagery.experiments.{name}").EXPERIMENT


def experiments():
    """The protocol of every experiment, in the order of :data:`EXPERIMENTS`."""
    for name in EXPERIMENTS:
        yield experiment(name)


def register_configs() -> None:
    """Store the schemas in Hydra's ConfigStore (called before composing)."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    for e in experiments():
        cs.store(group="experiment", name=f"{e.name}_schema", node=e.config)


def _experiment_in(text: str) -> str | None:
    """The experiment whose schema a Hydra or OmegaConf message names (``object_type=Exp6Config``,
    ``not in 'Exp5Config'``), if any."""
    return next((e.name for e in experiments() if re.search(rf"\b{e.config.__name__}\b", text)), None)


def schema_keys(experiment: str | None = None) -> list[str]:
    """Every dotted key a run may set: the top level's and those of ``experiment``'s schema (of
    every experiment when None)."""
    keys = [k for k in flatten(Config(experiment=None)) if k != "experiment"]  # type: ignore[arg-type]
    for e in experiments():
        if experiment is None or e.name == experiment:
            keys += [k for k in flatten(e.config(), "experiment.") if k not in keys]
    return keys


def did_you_mean(key: str, experiment: str | None = None) -> str:
    """`` (did you mean 'experiment.map_size'?)`` for a misspelt ``key``: the closest key of the
    schema (difflib), or ``""`` when none is close."""
    import difflib

    keys = schema_keys(experiment)
    if "." not in key:  # a top-level name: the top level's keys and groups (experiment, vision, ...)
        keys = list(dict.fromkeys(["experiment"] + [k.split(".")[0] for k in keys]))
    close = difflib.get_close_matches(key, keys, n=1, cutoff=0.75)
    return f" (did you mean {close[0]}?)" if close else ""


def not_a_key(key: str, experiment: str | None = None) -> str:
    """The refusal of ``key``, which is no key of this release (a misspelt key, or one of a 0.x
    release, which moved or went): the closest key, the version, where earlier keys are listed."""
    from .core.manifest import current_version

    if not key.startswith("experiment."):  # a top-level name (the experiments' keys are those that moved)
        return f"{key} is not a setting{did_you_mean(key, experiment)}"
    where = f"{experiment} in " if experiment else ""
    return (f"{key} is not a key of {where}neuroimagery {current_version()}{did_you_mean(key, experiment)}; "
            "keys of 0.x releases: CHANGELOG.md")


def unknown_key_message(text: str) -> str | None:
    """For Hydra's refusal of a key that is not in the schema (``Key 'map_sise' not in
    'Exp3Config'``): one line naming the key, with the closest existing key; None for other errors."""
    m = re.search(r"full_key: (\S+)", text)
    if m is None or " not in " not in text:
        return None
    key = m.group(1)
    experiment = _experiment_in(text)
    return not_a_key(key, experiment)


def _unknown_keys(node: DictConfig, path: str = "") -> list[str]:
    """Keys present in ``node`` but not declared by its dataclass schema (e.g. added with ``+key=``)."""
    out = []
    typ = OmegaConf.get_type(node)
    declared = {f.name for f in dataclasses.fields(typ)} if dataclasses.is_dataclass(typ) else None
    for key in node.keys():
        full = f"{path}{key}"
        if declared is not None and key not in declared:
            out.append(full)
        child = node._get_node(key)
        if isinstance(child, DictConfig) and not child._is_missing() and not child._is_none():
            out += _unknown_keys(child, full + ".")
    return out


def check_finite(conf: Any) -> None:
    """Every float of ``conf`` (a dataclass, mapping or DictConfig) is finite."""
    for key, value in _leaves(conf):
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, float) and not math.isfinite(v):
                raise UserInputError(f"{key} must be a finite number, got {v}")


def _leaves(conf: Any):
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(conf, DictConfig):
            conf = OmegaConf.to_container(conf, resolve=False, throw_on_missing=False)
            conf.pop("hydra", None)
    except ImportError:  # pragma: no cover
        pass
    return flatten(conf).items()


def validate(cfg: DictConfig | Config) -> Config:
    """Turn a composed config into checked objects; a bad value raises :class:`UserInputError`."""
    if isinstance(cfg, Config):
        check_finite(cfg)
        return cfg
    if not isinstance(cfg.get("experiment"), DictConfig):
        raise UserInputError("invalid configuration: choose an experiment, e.g. experiment=exp4")
    unknown = [k for k in _unknown_keys(cfg) if not k.startswith("hydra")]
    name = cfg.experiment.get("name") if "name" in cfg.experiment else None
    experiment = name if name in EXPERIMENTS else None
    if unknown:
        raise UserInputError(f"invalid configuration: {not_a_key(unknown[0], experiment)}"
                             + (f" (also unknown: {', '.join(unknown[1:])})" if unknown[1:] else ""))
    check_finite(cfg)
    try:
        obj = OmegaConf.to_object(cfg)
    except (ValueError, OmegaConfBaseException) as e:
        msg = str(e).split("\n")[0]
        raise UserInputError(f"invalid configuration: {msg}") from None
    if not isinstance(obj, Config):
        raise UserInputError("invalid configuration: the primary config must extend base_config")
    name = getattr(obj.experiment, "name", None)
    if name is None:
        raise UserInputError("invalid configuration: choose an experiment, e.g. experiment=exp4")
    quick = getattr(obj.experiment, "quick", None)
    if obj.preset == "quick" and hasattr(quick, "participants"):  # docs/choices.md, "Quick presets", rule 2
        obj.participants = min(obj.participants, quick.participants)
    return obj
