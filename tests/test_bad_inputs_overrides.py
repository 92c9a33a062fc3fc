"""Empty and deleted values, and checks derived from several settings.

A setting given as an empty string (what ``checkpoint=$DIR`` gives when ``DIR`` is unset) and a
Hydra deletion (``~key``) are refused, naming the key, whatever the key: neither silently falls back
to the default. A check that depends on several settings names all of them, those the user set
first (Exp 6's view of the objects: the field of view, the image, the distance, the cube size).
"""
from __future__ import annotations

import pytest

from support_bad_inputs import composing, evaluating, hydra_reporter, no_training, refused  # noqa: F401 (fixtures)

DELETED = ["seed", "participants", "checkpoint", "preset", "threads", "experiment.eta", "logger", "vision", "experiment"]


@pytest.mark.parametrize("key", DELETED)
def test_a_deleted_setting_is_refused_naming_it(capsys, hydra_reporter, key):
    over = ["experiment=exp4", f"~{key}"] if key != "experiment" else [f"~{key}"]
    refused(capsys, composing(*over), f"~{key}: a setting cannot be deleted", f"({key}=...)")


EMPTY = [
    ["experiment=demo", "checkpoint="],
    ["experiment=demo", "checkpoint=''"],
    ["experiment=demo", "checkpoint=' '"],
    ["experiment=exp1", "stimuli=folder", "stimuli.path="],
    ["experiment=exp5", "experiment.engine.reuse_libraries="],
    ["experiment=demo", "hydra.run.dir="],
    ["experiment=demo", "logger="],
]


@pytest.mark.parametrize("over", EMPTY, ids=[o[-1] for o in EMPTY])
def test_an_empty_value_is_refused_naming_the_key(capsys, hydra_reporter, over):
    key = over[-1].split("=")[0]
    refused(capsys, composing(*over), f"{key}=", "is empty (an unset shell variable?)")


def test_an_empty_path_built_in_python_is_refused_before_any_work(tmp_path, capsys, no_training):
    """The same refusal without Hydra's command line (a configuration composed or built in Python)."""
    from neuroimagery.app import cli
    from neuroimagery.app.run import evaluate

    from conftest import make_cfg

    cfg = make_cfg("experiment=demo")
    cfg.checkpoint = ""
    refused(capsys, lambda: cli.friendly_errors(evaluate)(cfg, out_dir=tmp_path / "run"), "checkpoint=''", "is empty")
    assert not (tmp_path / "run").exists()


def test_a_sweep_and_a_plain_value_pass(capsys, hydra_reporter):
    from hydra._internal import utils as hydra_utils

    cfg = hydra_utils.run_and_report(composing("experiment=demo", "seed=3", "checkpoint=null"))
    assert cfg.seed == 3 and cfg.checkpoint is None


VIEW = [  # Exp 6: the check of the objects' size in the eye's image depends on five settings
    (["experiment.view.fov_deg=179"], "experiment.view.fov_deg=179 (set here), with experiment.view.image_height=240, "
     "experiment.view.object_distance=0.5, experiment.view.cube_edge=0.025: one cube covers"),
    (["experiment.view.fov_deg=1"], "experiment.view.fov_deg=1 (set here), with experiment.view.image_width=320"),
    (["experiment.view.cube_edge=0.1"], "experiment.view.cube_edge=0.1 (set here), with experiment.view.fov_deg=30"),
]


@pytest.mark.parametrize("over,needle", VIEW, ids=[o[0] for o, _ in VIEW])
def test_a_derived_check_names_every_setting_it_depends_on(tmp_path, capsys, no_training, over, needle):
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp6", "participants=1", *over), needle)
