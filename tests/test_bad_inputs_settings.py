"""Settings that can be judged before any work are judged then: names of stimulus sets, module
paths, runs named for reuse, object placement and scale, thresholds; misspelt keys and keys of 0.x get
one line that says what was meant. Each refusal: exit 2, one ``error:`` line, nothing claimed."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from support_bad_inputs import (composing, evaluating, hydra_reporter, no_training, refused,  # noqa: F401 (fixtures)
                                training)

ROOT = Path(__file__).resolve().parents[1]

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
    (["experiment=exp6", "participants=1", "experiment.view.red_threshold=300"], "experiment.view.red_threshold=300"),
    (["experiment=exp6", "participants=1", "experiment.view.red_threshold=250"], "no pixel of the object is that red"),
    (["experiment=exp6", "participants=1", "experiment.view.red_threshold=0"], "experiment.view.red_threshold"),
    (["experiment=exp6", "participants=1", "experiment.view.object_distance=100"], "depth range"),
    (["experiment=exp6", "participants=1", "experiment.view.object_distance=0.06"], "experiment.view.object_distance=0.06"),
    (["experiment=exp6", "participants=1", "experiment.view.object_distance=0.5", "experiment.view.cube_edge=0.1"],
     "field of view"),
    (["experiment=exp6", "participants=1", "experiment.view.object_distance=2.5", "experiment.view.cube_edge=0.0001"],
     "pixel"),
    (["experiment=exp6", "participants=1", "experiment.cube_voxels=1000"], "experiment.cube_voxels=1000"),
    (["experiment=exp6", "participants=1", "experiment.cube_voxels=2.5"], "scale rule"),
    (["experiment=exp6", "participants=1", "experiment.fm.memory_mb=0.01"], "experiment.fm.memory_mb=0.01"),
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
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp6", "participants=1", "experiment.objects.test=20"),
            "experiment.objects.test")


MESSAGE_CASES = [  # keys: misspelt, of a 0.x release, or an experiment's own key with a bad value
    (["experiment=exp6", "experiment.selection.max_steps=abc"], "experiment.selection.max_steps", "is not a key"),
    (["experiment=exp6", "experiment.posture_iterations=5"], "experiment.posture_iterations is not a key of exp6 in "
                                                             "neuroimagery", None),
    (["experiment=exp6", "experiment.eta_fm=0.2"], "did you mean experiment.fm.eta?", None),
    (["experiment=exp3", "experiment.map_sise=3"], "did you mean experiment.map_size?", None),
    (["experiment=exp3", "experiment.fm.imges=3"], "did you mean experiment.fm.images?", None),
    (["experiment=exp4", "participans=3"], "did you mean participants?", None),
    (["experiment=exp5", "experiment.brain.etta=0.1"], "did you mean experiment.brain.eta?", None),
    (["experiment=exp6", "experiment.view.red_treshold=50"], "did you mean experiment.view.red_threshold?", None),
    (["experiment=exp4", "experiment.posture_iterations=5"], "did you mean experiment.posture.iterations?", None),
    (["experiment=exp5", "experiment.c3_eta=5"], "(did you mean experiment.brain.c3_eta?); keys of 0.x releases: "
                                                 "CHANGELOG.md", None),
    (["experiment=exp4", "experiment.zzzz=1"], "experiment.zzzz is not a key of exp4 in neuroimagery", "did you mean"),
]


@pytest.mark.parametrize("over,needle,absent", MESSAGE_CASES, ids=[" ".join(o) for o, _, _ in MESSAGE_CASES])
def test_key_messages_say_what_was_meant(capsys, hydra_reporter, over, needle, absent):
    line = refused(capsys, composing(*over), needle)
    assert absent is None or absent not in line


def test_a_misspelt_key_added_with_plus_gets_the_closest_key(tmp_path, capsys, no_training):
    refused(capsys, evaluating(tmp_path / "run", "experiment=exp3", "+experiment.map_sise=3"),
            "experiment.map_sise", "did you mean experiment.map_size?")


# ------------------------------------------------- numbers, choices and keys of every experiment
CONFIG_CASES = [
    # numbers that are not finite, or out of range
    (["experiment=exp4", "experiment.ppc.noise_amplitude=inf"], "experiment.ppc.noise_amplitude"),
    (["experiment=exp2", "experiment.proprio_gain=nan"], "experiment.proprio_gain"),
    (["experiment=exp1", "experiment.hebb_eta=nan"], "experiment.hebb_eta"),
    (["experiment=exp3", "experiment.m1_centre_sigma=inf"], "experiment.m1_centre_sigma"),
    (["experiment=exp5", "experiment.brain.eta=nan"], "experiment.brain.eta"),
    (["experiment=demo", "experiment.noise=inf"], "experiment.noise"),
    (["experiment=exp4", "vision.gamma=nan"], "vision.gamma"),
    (["experiment=exp4", "experiment.ppc.angles=[0,nan]"], "experiment.ppc.angles"),
    (["experiment=exp5", "experiment.acquisition.explore_patience=0"], "experiment.acquisition.explore_patience"),
    (["experiment=exp1", "participants=0"], "participants"),
    (["experiment=exp3", "seed=-1"], "seed"),
    (["experiment=exp4", "preset=huge"], "preset"),
    (["experiment=exp2", "threads=-2"], "threads"),
    (["experiment=exp5", "experiment.engine.n_jobs=0"], "experiment.engine.n_jobs"),
    (["experiment=exp2", "experiment.som.method=fast"], "experiment.som.method"),
    (["experiment=exp5", "experiment.situations=[nowhere]"], "experiment.situations"),
    (["experiment=exp4", "logger.kind=wandb"], "logger.kind"),
    (["experiment=exp1", "vision.kind=laser"], "vision.kind"),
    (["experiment=demo", "+experiment.stp_deg=3"], "experiment.stp_deg"),
    (["experiment=exp2", "+experiment.som_eta=0.2"], "did you mean experiment.som.eta?"),  # a 0.x key added with +
    (["experiment=exp1", "experiment.field.tau=0"], "experiment.field.tau"),  # a group's own range check
    (["experiment=exp4", "experiment.fm.batch=0"], "experiment.fm.batch"),
    # keys that would have no effect in this experiment or with these options
    (["experiment=exp4", "vision.size=16"], "vision.size"),
    (["experiment=exp1", "vision.gaze_jitter_deg=1"], "vision.gaze_jitter_deg"),
    (["experiment=exp4", "stimuli.path=/tmp"], "stimuli.path"),
    (["experiment=exp5", "participants=3"], "participants"),
    (["experiment=exp5", "vision.noise_std=5"], "vision.noise_std"),
    (["experiment=demo", "stimuli=folder", "stimuli.path=/tmp"], "stimuli.kind"),
    (["experiment=exp4", "logger=none", "logger.map_images=false"], "logger.map_images"),
    (["experiment=exp3", "experiment.quick.objects=2"], "experiment.quick.objects"),
    (["experiment=exp4", "preset=quick", "experiment.fm.images=100"], "experiment.fm.images"),
    (["experiment=exp4", "experiment.lca.k=0.7"], "experiment.lca.k"),  # the leak is set by rule R2
    (["experiment=exp4", "experiment.noise_tests=[]", "experiment.ppc.noise_amplitude=0.3"], "experiment.ppc.noise_amplitude"),
    (["experiment=exp5", "preset=quick", "experiment.repetitions=5"], "experiment.repetitions"),
    (["experiment=exp2", "threads=1", "experiment.auto_threads=2"], "experiment.auto_threads"),
]


@pytest.mark.parametrize("over,needle", CONFIG_CASES, ids=[" ".join(o) for o, _ in CONFIG_CASES])
def test_bad_settings_are_refused_before_any_work(tmp_path, capsys, no_training, over, needle):
    refused(capsys, evaluating(tmp_path / "run", *over), needle)
    assert not (tmp_path / "run").exists()  # nothing written


def test_checkpoint_is_refused_in_training(tmp_path, capsys, no_training):
    refused(capsys, training(tmp_path / "run", "experiment=demo", f"checkpoint={tmp_path}"), "checkpoint=")


@pytest.mark.parametrize("over,needle", [(["experiment=demo", "experiment.stp_deg=3"], "stp_deg"),
                                         (["experiment=demo", "seed=abc"], "seed"),
                                         # a key of 0.x that moved into a group: the closest key is its new place
                                         (["experiment=exp1", "experiment.field_tau=5"], "did you mean experiment.field.tau?"),
                                         (["experiment=exp2", "experiment.cluster_sigma=2"], "experiment.som.cluster_sigma"),
                                         (["experiment=exp3", "experiment.quick_fm_images=9"], "experiment.quick.fm_images"),
                                         (["experiment=exp4", "experiment.eta_posture=0.2"], "eta_posture is not a key of exp4")])
def test_hydra_composition_errors_are_one_line(capsys, hydra_reporter, over, needle):
    refused(capsys, composing(*over), needle)


# ------------------------------------------------------------------------ the command line
@pytest.mark.parametrize("args,needle", [(["experiment.stp_deg=1"], "stp_deg"), (["experiment.eta=nan"], "experiment.eta")])
def test_the_command_line_prints_one_error_line(tmp_path, args, needle):
    p = subprocess.run([sys.executable, str(ROOT / "train.py"), "experiment=demo", f"hydra.run.dir={tmp_path / 'r'}", *args],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 2, p.stderr
    assert [ln for ln in p.stderr.splitlines() if ln.strip()] == [ln for ln in p.stderr.splitlines() if ln.startswith("error:")]
    assert needle in p.stderr and "Traceback" not in p.stderr
