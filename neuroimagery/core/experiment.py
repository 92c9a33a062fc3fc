"""What the runner needs of an experiment: one :class:`Experiment` per experiment package.

An experiment is a subpackage ``neuroimagery.experiments.<name>`` whose ``__init__`` defines
``EXPERIMENT = Experiment(...)``, plus its configuration ``conf/experiment/<name>.yaml``; nothing
else is registered anywhere. The runner (``neuroimagery.app.run``), the checks before any work
(``neuroimagery.validation``, ``neuroimagery.core.resources``), the manifest and the pooling read
these fields and nothing else of the package.

What the checks read (the schema, the declarations, ``memory_estimate``, ``check_inputs``,
``ineffective_keys``) comes from light modules of the package (its ``config``), so that a refused
setting is answered without importing torch or the analysis libraries; the phases (``train``,
``load``, ``evaluate``, ``report``, ...) are :class:`lazy` references to its ``protocol`` module,
imported on their first call."""
from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import Any, Callable, Optional


class lazy:
    """The function ``name`` of module ``module``, imported on its first call:
    ``lazy("neuroimagery.experiments.exp4.protocol", "train")(conf, run)``."""

    __slots__ = ("module", "name", "_target")

    def __init__(self, module: str, name: str) -> None:
        self.module, self.name, self._target = module, name, None

    def resolve(self) -> Callable[..., Any]:
        """The function itself (its module imported now if it was not yet)."""
        if self._target is None:
            self._target = getattr(importlib.import_module(self.module), self.name)
        return self._target

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.resolve()(*args, **kwargs)

    def __repr__(self) -> str:
        return f"lazy({self.module!r}, {self.name!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, lazy) and (self.module, self.name) == (other.module, other.name)

    def __hash__(self) -> int:
        return hash((self.module, self.name))

    def __reduce__(self):
        return lazy, (self.module, self.name)


def phases(package: str, *names: str) -> dict[str, lazy]:
    """The fields ``names`` of an :class:`Experiment` as :class:`lazy` references to the functions
    of the same names in ``package``'s ``protocol`` module: ``Experiment(name=..., **phases(__name__,
    "train", "load", "evaluate", "report"), ...)``."""
    return {n: lazy(f"{package}.protocol", n) for n in names}


@dataclass(frozen=True)
class Experiment:
    """The protocol of one experiment.

    Required: ``name``, the configuration schema ``config`` (a dataclass: the ``experiment.*``
    keys), ``train(conf, run) -> trained``, ``load(conf, checkpoint_dir) -> trained`` and
    ``evaluate(conf, run, trained) -> summary``. The rest is optional. Any function may be given
    as a :class:`lazy` reference; those the checks before work call should live in a module that
    imports nothing heavy.

    - ``report(conf, run, summary)``: writes ``report.md`` (a generic one otherwise);
    - ``checkpoints``: the checkpoint files a trained run holds (``checkpoints/<name>.pt``);
    - ``inputs``: the top-level groups the experiment reads (``"vision"``, ``"stimuli"``); the
      settings of the others are refused as ineffective;
    - ``min_objects``: how many shapes a user's stimulus folder must hold;
    - ``runtime_keys`` / ``test_keys``: ``experiment.*`` keys that change speed only / the test
      only (a checkpoint trained with other values of them is still usable);
    - ``memory_estimate(conf) -> [Need]``: the largest allocations, checked against the memory;
    - ``check_inputs(conf)``: refuses what can be checked without the work;
    - ``ineffective_keys(conf) -> {key: reason}``: settings that would change nothing;
    - ``trained_count(conf) -> (count, unit)``: what the training phase reports it trained;
    - ``effects(trials) -> [row]``: the effects a pooled report tests;
    - ``pool_runs(run_dirs) -> (summary, rows, report)``: the experiment pools its runs itself,
      with ``pool_free_keys``: the ``experiment.*`` settings its runs may differ in besides the seed,
      and ``pool_rows``: the file its pooled rows are written to.
    """

    name: str
    config: type
    train: Callable[..., Any]
    load: Callable[..., Any]
    evaluate: Callable[..., dict]
    report: Optional[Callable[..., None]] = None
    checkpoints: tuple[str, ...] = ("model",)
    inputs: tuple[str, ...] = ()
    min_objects: int = 1
    runtime_keys: tuple[str, ...] = ()
    test_keys: tuple[str, ...] = ()
    memory_estimate: Optional[Callable[..., list]] = None
    check_inputs: Optional[Callable[..., None]] = None
    ineffective_keys: Optional[Callable[..., dict]] = None
    trained_count: Optional[Callable[..., tuple]] = None
    effects: Optional[Callable[..., list]] = None
    pool_runs: Optional[Callable[..., tuple]] = None
    pool_free_keys: tuple[str, ...] = ()
    pool_rows: str = "trials.csv"

    def import_phases(self) -> None:
        """Import now what the :class:`lazy` fields refer to (the protocol), so that the time of a
        phase does not hold the imports."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, lazy):
                value.resolve()
