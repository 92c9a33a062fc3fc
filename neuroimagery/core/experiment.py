"""What the runner needs of an experiment: one :class:`Experiment` per experiment package.

An experiment is a subpackage ``neuroimagery.experiments.<name>`` whose ``__init__`` defines
``EXPERIMENT = Experiment(...)``, plus its configuration ``conf/experiment/<name>.yaml``; nothing
else is registered anywhere. The runner (``neuroimagery.app.run``), the checks before any work
(``neuroimagery.validation``, ``neuroimagery.core.resources``), the manifest and the pooling read
these fields and nothing else of the package."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional


@dataclass(frozen=True)
class Experiment:
    """The protocol of one experiment.

    Required: ``name``, the configuration schema ``config`` (a dataclass: the ``experiment.*``
    keys), ``train(conf, run) -> trained``, ``load(conf, checkpoint_dir) -> trained`` and
    ``evaluate(conf, run, trained) -> summary``. The rest is optional:

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
      with ``pool_free_keys``: the ``experiment.*`` settings its runs may differ in besides the seed.
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
