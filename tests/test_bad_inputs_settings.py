"""Settings that can be judged before any work are judged then: names of stimulus sets, module
paths, runs named for reuse, object placement and scale, thresholds; misspelt and moved keys get
one line that says what was meant. Each refusal: exit 2, one ``error:`` line, nothing claimed."""
from __future__ import annotations

import json

import pytest

from support_bad_inputs import composing, evaluating, hydra_reporter, no_training, refused  # noqa: F401 (fixtures)

SETTING_CASES = [
    (["experiment=exp3", "experiment.train_set=nosuchset"], "experiment.train_set='nosuchset'"),
    (["experiment=exp3", "experiment.recog_set=exp3-z"], "did you mean 'exp3-c'"),
    (["experiment=exp3", "experiment.gen2_set=exp3-"], "experiment.gen2_set"),
    (["experiment=exp4", "experiment.gen1_set=exp4-b"], "did you mean 'exp4-B'"),
    (["experiment=exp4", "experiment.train_set=/no/such/folder"], "experiment.train_set"),
    (["experiment=exp5", "experiment.world.environment=nosuch.module:Thing"], "cannot import 'nosuch.module'"),
    (["experiment=exp5", "experiment.world.environment=json:Thing"], "has no class 'Thing'"),
    (["experiment=exp5", "experiment.world.environment=nocolon"], "experiment.world.environment"),
    (["experiment=exp5", "experiment.hp2_ages=[-5,14,16,18,20,22]"], "experiment.hp2_ages[0] must be >= 0"),
    (["experiment=exp5", "experiment.hp1_ages=[14,16,-18,20,22]"], "experiment.hp1_ages[2]"),
    (["experiment=exp5", "experiment.hp2_trials=[0,2,4,6,8,-10]"], "experiment.hp2_trials[5]"),
    (["experiment=exp6", "participants=1", "experiment.red_threshold=300"], "experiment.red_threshold=300"),
    (["experiment=exp6", "participants=1", "experiment.red_threshold=250"], "no pixel of the object is that red"),
    (["experiment=exp6", "participants=1", "experiment.red_threshold=0"], "experiment.red_threshold"),
    (["experiment=exp6", "participants=1", "experiment.object_distance=100"], "depth range"),
    (["experiment=exp6", "participants=1", "experiment.object_distance=0.06"], "experiment.object_distance=0.06"),
    (["experiment=exp6", "participants=1", "experiment.object_distance=0.5", "experiment.cube_edge=0.1"],
     "field of view"),
    (["experiment=exp6", "participants=1", "experiment.object_distance=2.5", "experiment.cube_edge=0.0001"],
     "pixel"),
    (["experiment=exp6", "participants=1", "experiment.cube_voxels=1000"], "experiment.cube_voxels=1000"),
    (["experiment=exp6", "participants=1", "experiment.cube_voxels=2.5"], "scale rule"),
    (["experiment=exp6", "participants=1", "experiment.fm_memory_mb=0.01"], "experiment.fm_memory_mb=0.01"),
    (["experiment=exp6", "participants=1", "experiment.grid=7"], "experiment.grid"),
    (["experiment=exp1", "experiment.som.method=fast"], "experiment.som.method must be one of"),
    (["experiment=exp2", "experiment.som.eta=1.5"], "experiment.som.eta must be in (0, 1]"),
    (["experiment=exp1", "experiment.field.max_cycles=0"], "experiment.field.max_cycles"),
    (["experiment=exp4", "experiment.posture.iterations=0"], "experiment.posture.iterations"),
    (["experiment=exp3", "vision.gamma=9"], "vision.gamma must be in [0.2, 5]"),
    (["experiment=exp3", "logger.sample_trials=-1"], "logger.sample_trials"),
]


@pytest.mark.parametrize("over,needle", SETTING_CASES, ids=[" ".join(o) for o, _ in SETTING_CASES])
def test_settings_are_judged_before_any_work(tmp_path, capsys, no_training, over, needle):
    refused(capsys, evaluating(tmp_path / "run", *over), needle)
    assert not (tmp_path / "run").exists()  # nothing claimed


@pytest.mark.parametrize("manifest,needle", [({"experiment": "exp4"}, "a run of exp4, not of exp5"), (None, "no task files")])
def test_reuse_libraries_must_name_a_run_of_exp5(tmp_path, capsys, no_training, manifest, needle):
    other = tmp_path / "other"
    (other / "checkpoints").mkdir(parents=True)
    if manifest is not None:
        (other / "manifest.json").write_text(json.dumps(manifest))
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp5", f"experiment.engine.reuse_libraries={other}"),
            "experiment.engine.reuse_libraries", needle)


@pytest.mark.slow  # the generator tries its 100000 candidates first: about 4 s on an idle machine
def test_the_objects_the_generator_cannot_find_are_refused_before_training(tmp_path, capsys, no_training):
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp6", "participants=1", "experiment.test_objects=20"),
            "experiment.test_objects")


MESSAGE_CASES = [  # keys: misspelt, moved, or an experiment's own key with a bad value
    (["experiment=exp6", "experiment.posture_iterations=abc"], "experiment.posture_iterations", "has moved"),
    (["experiment=exp3", "experiment.map_sise=3"], "did you mean experiment.map_size?", None),
    (["experiment=exp3", "experiment.fm.imges=3"], "did you mean experiment.fm.images?", None),
    (["experiment=exp4", "participans=3"], "did you mean participants?", None),
    (["experiment=exp5", "experiment.brain.etta=0.1"], "did you mean experiment.brain.eta?", None),
    (["experiment=exp6", "experiment.red_treshold=50"], "did you mean experiment.red_threshold?", None),
    (["experiment=exp4", "experiment.posture_iterations=5"], "it is experiment.posture.iterations now", None),
    (["experiment=exp5", "experiment.c3_eta=5"], "it is experiment.brain.c3_eta now", None),
    (["experiment=exp4", "experiment.zzzz=1"], "experiment.zzzz is not a setting of exp4", "did you mean"),
]


@pytest.mark.parametrize("over,needle,absent", MESSAGE_CASES, ids=[" ".join(o) for o, _, _ in MESSAGE_CASES])
def test_key_messages_say_what_was_meant(capsys, hydra_reporter, over, needle, absent):
    line = refused(capsys, composing(*over), needle)
    assert absent is None or absent not in line


def test_a_misspelt_key_added_with_plus_gets_the_closest_key(tmp_path, capsys, no_training):
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp3", "+experiment.map_sise=3"),
            "experiment.map_sise", "did you mean experiment.map_size?")
