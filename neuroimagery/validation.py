"""Checks a run's whole configuration before any work starts.

:func:`check_run` refuses, with one :class:`~neuroimagery.core.errors.UserInputError` naming the key or
the file,

- a setting given as an empty string where its default is not (``checkpoint=''``);
- a number that is not finite (``nan`` slips through every range check written as a
  comparison, ``inf`` through every lower bound);
- a value outside the bounds its field declares (:mod:`neuroimagery.core.bounds`), the whole
  configuration walked, each key named by its full path;
- a key set to something other than its default that has no effect in this experiment or with
  these options (:func:`ineffective`), so a misplaced setting never passes silently;
- settings that need more memory, or threads than the cores, this process may use
  (:mod:`neuroimagery.core.resources`; ``allow_large=true`` skips this check);
- what the experiment's own ``check_inputs(conf)`` refuses (names of stimulus sets, a
  module path, object placement: whatever can be checked without the work);
- a stimulus folder that cannot be used (unreadable, truncated or oversized images, links that
  lead nowhere, no shape found, too few objects), before any training.

Whether a key was "set" is judged against the schema's defaults (the dataclasses), so a run
composed by Hydra and a :class:`~neuroimagery.config.Config` built in Python are checked alike.
An experiment (:class:`neuroimagery.core.experiment.Experiment`) may add its own rules with
``ineffective_keys(conf) -> {key: reason}``, ``memory_estimate(conf) -> [resources.Need]`` and
``check_inputs(conf)``, and declare ``inputs`` (the groups of what it sees: ``vision``,
``stimuli``) and ``min_objects`` (how many shapes a user folder must hold).

:func:`prepare` is what ``train.py`` and ``evaluate.py`` run before anything else: it reads only the
light modules of the experiment (its schema and checks), so a refusal comes before torch and the
experiment's protocol are imported.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from .config import Config, check_finite, experiment, validate
from .core.errors import UserInputError
from .core.experiment import Experiment
from .core.manifest import flatten

CAMERA_KEYS = ("robot_model", "eye", "image_width", "image_height", "fov_deg", "screen_distance",
               "object_width", "gaze_jitter_deg")


def user_set(conf) -> dict[str, Any]:
    """The keys of ``conf`` whose values differ from the schema's defaults."""
    defaults = flatten(Config(experiment=None))  # type: ignore[arg-type]
    defaults.pop("experiment", None)
    defaults.update(flatten(type(conf.experiment)(), "experiment."))
    values = flatten(conf)
    return {k: v for k, v in values.items() if k in defaults and _differs(v, defaults[k])}


def settings_named(conf, keys) -> str:
    """``key=value`` of every setting in ``keys`` (full paths) that a check derived from them
    depends on, those the user set first: ``experiment.view.fov_deg=170 (set here), with
    experiment.view.object_distance=0.5, ...`` (a refusal names all it depends on, the one changed first)."""
    values, changed = flatten(conf), user_set(conf)

    def show(k):
        v = values.get(k)
        return f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"

    first = [show(k) for k in keys if k in changed]
    rest = [show(k) for k in keys if k not in changed]
    if not first:
        return ", ".join(rest)
    return ", ".join(first) + " (set here)" + (", with " + ", ".join(rest) if rest else "")


def _differs(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return list(a) != list(b)
    return a != b


def ineffective(conf, module) -> dict[str, str]:
    """``{key: why it has no effect}`` for every key of this run that does nothing here."""
    name = conf.experiment.name
    inputs = module.inputs
    out: dict[str, str] = {}
    if "vision" not in inputs:
        out.update({f"vision.{f.name}": f"{name} does not see through the eye"
                    for f in dataclasses.fields(conf.vision)})
    else:
        out["vision.size"] = (f"{name} sets the size of its edge maps itself"
                              + (" (experiment.map_size)" if hasattr(conf.experiment, "map_size") else " (32)"))
        if conf.vision.kind == "direct":
            out.update({f"vision.{k}": "it acts on the camera path only (vision=camera)" for k in CAMERA_KEYS})
    if "stimuli" not in inputs:
        out.update({f"stimuli.{f.name}": f"{name} has no stimulus sets" for f in dataclasses.fields(conf.stimuli)})
    elif conf.stimuli.kind == "builtin":
        out["stimuli.path"] = "it is read with stimuli=folder only"
    if conf.logger.kind == "none":
        out["logger.map_images"] = "logger=none writes no TensorBoard files"  # sample_trials also feeds figures
    if conf.preset == "full":
        quick = getattr(conf.experiment, "quick", None)  # the group of what preset=quick shrinks
        if dataclasses.is_dataclass(quick):
            out.update({f"experiment.quick.{f.name}": "it acts with preset=quick only" for f in dataclasses.fields(quick)})
        out.update({f"experiment.{f.name}": "it acts with preset=quick only"
                    for f in dataclasses.fields(conf.experiment) if f.name.startswith("quick_")})
    if conf.threads and hasattr(conf.experiment, "auto_threads"):
        out["experiment.auto_threads"] = "it acts only when threads=0"
    extra = module.ineffective_keys
    if extra is not None:
        out.update(extra(conf))
    return out


def check_empty(conf) -> None:
    """Refuse a setting given as an empty string where its default is not (a path left empty by an
    unset shell variable must not read as "not set")."""
    for k, v in user_set(conf).items():
        if isinstance(v, str) and not v.strip():
            raise UserInputError(f"{k}={v!r} is empty (an unset shell variable?): give it a value, or leave it out "
                                 "for its default")


def check_ineffective(conf, module) -> None:
    """Refuse every key set away from its default that has no effect in this run."""
    bad = ineffective(conf, module)
    hits = [f"{k}={v!r} has no effect: {bad[k]}" for k, v in user_set(conf).items() if k in bad]
    if hits:
        raise UserInputError("; ".join(hits))


def check_stimulus_folder(conf, module) -> None:
    """Load a user stimulus folder now, so a bad one is refused before any training: every file
    listed, sized from its header and fully decoded (``vision.image_files``), by name."""
    if "stimuli" not in module.inputs or conf.stimuli.kind != "folder":
        return
    from .vision.stimulus_sets import load_folder

    folder = Path(conf.stimuli.path)
    if not folder.is_dir():
        raise UserInputError(f"stimuli.path {str(folder)!r} is not a folder")
    sset = load_folder(folder)
    need = module.min_objects
    if len(sset.objects) < need:
        raise UserInputError(f"stimulus folder {folder} holds {len(sset.objects)} shape(s); "
                             f"{conf.experiment.name} needs at least {need} (a shape and its mirror)")


def check_run(conf, module) -> None:
    """Every check of this module, cheapest first."""
    from .core.bounds import check_declared
    from .core.resources import check_resources

    check_finite(conf)
    check_empty(conf)
    check_declared(conf)
    check_ineffective(conf, module)
    check_resources(conf, module)
    extra = module.check_inputs
    if extra is not None:
        extra(conf)
    check_stimulus_folder(conf, module)


def prepare(cfg) -> tuple[Config, Experiment]:
    """A run's configuration as checked objects and its experiment: :func:`~neuroimagery.config.validate`
    then :func:`check_run`; a refusal raises :class:`UserInputError`."""
    conf = validate(cfg)
    module = experiment(conf.experiment.name)
    check_run(conf, module)
    return conf, module
