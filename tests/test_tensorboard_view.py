"""TensorBoard as a researcher opens it: every experiment writes a training curve, the Scalars tab's
first group (tags sort by name) is a curve, HParams shows the settings as the run used them, and
the images and the figures' map panels share one colour scale."""
import matplotlib
import numpy as np
import pytest
import torch
from conftest import make_cfg
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from neuroimagery.core import manifest as mf
from neuroimagery.analysis.figures import _cell
from neuroimagery.config import validate
from neuroimagery.core.logger import COLOUR_MAP, _to_image
from neuroimagery.nn import monitor
from neuroimagery.nn.som import winner_changes
from neuroimagery.app.run import evaluate, train


def _scalars(root):
    ea = EventAccumulator(str(root / "tb"), size_guidance={"scalars": 0}).Reload()
    return ea, {t: len(ea.Scalars(t)) for t in ea.Tags()["scalars"]}


@pytest.mark.parametrize("exp", ["exp1", "exp2", "demo"])
def test_every_experiment_writes_a_training_curve(tmp_path, exp):
    over = ("preset=quick",) if exp != "demo" else ()
    train(make_cfg(f"experiment={exp}", "participants=1", "progress=false", *over), out_dir=tmp_path)
    _, tags = _scalars(tmp_path)
    assert any(t.startswith("train/") and n > 1 for t, n in tags.items()), tags


# a small quick run of each experiment (the sizes only shorten it; the tags are the full run's). Exp 4
# logs no sample trial's maps (images, not scalars) and builds 2 looks per test item: the same
# scalar tags with the same counts of steps, in less than half the time
_SMALL = {
    "exp1": ("participants=1",),
    "exp2": ("participants=1",),
    "exp3": ("participants=1", "experiment.quick.fm_images=200"),
    "exp4": ("participants=1", "experiment.quick.fm_images=200", "logger.sample_trials=0", "experiment.percept.looks=2"),
    "exp5": ("experiment.world.environment=support_tool_env:StandInToolEnv", "experiment.engine.n_jobs=1",
             "experiment.quick.repetitions=1", "experiment.acquisition.max_epochs=2",
             "experiment.acquisition.explore_max_rollouts=120", "experiment.hp2_trials=[0,2]", "experiment.hp2_ages=[14,16]"),
    "exp6": ("participants=1", "experiment.grid=10", "experiment.quick.fm_images=16", "experiment.quick.chains=8",
             "experiment.quick.objects=1", "experiment.objects.train=1", "experiment.test_angles=[0,60,120,180]",
             "experiment.step_deg=30", "experiment.search.iterations=20"),
    "demo": ("participants=2",),
}


@pytest.mark.parametrize("exp", sorted(_SMALL))
def test_the_scalars_tab_opens_on_a_curve(tmp_path, exp):
    """TensorBoard's Scalars page groups the tags by their prefix before '/', sorted: the first group
    holds a curve (a tag of more than one step), not one-point values."""
    if exp == "exp5":
        import sys
        from pathlib import Path
        sys.path.insert(0, str(Path(__file__).parent))  # the stand-in world of tests/support_tool_env.py
    over = ("preset=quick",) if exp != "demo" else ()
    evaluate(make_cfg(f"experiment={exp}", "progress=false", "logger=tensorboard", *over, *_SMALL[exp]), out_dir=tmp_path)
    _, tags = _scalars(tmp_path)
    first = sorted(tags)[0].split("/")[0]
    assert any(n > 1 for t, n in tags.items() if t.split("/")[0] == first), (first, tags)
    metrics = [t for t in tags if t.startswith("values/")]
    assert metrics and all(tags[t] == 1 for t in metrics)


def test_winner_changes_counts_a_patterns_new_winner():
    order = torch.tensor([[0, 1, 0, 1, 0, 0], [2, 2, 2, 2, 1, 1]])
    winners = torch.tensor([[5, 6, 5, 7, 4, 4], [1, 2, 2, 2, 3, 0]])
    got = []
    with monitor.to(lambda tag, v, s: got.append((s, v))):
        winner_changes("t", order, winners, offset=10, points=6)
    # by step: p0: -, -, same, changed, changed, same; p1: -, changed, same, same, -, changed
    assert got == [(12, 1.0), (13, 0.0), (14, 0.5), (15, 1.0), (16, 0.5)]


def test_hparams_show_the_quick_values():
    for exp, key, quick_key in (("exp4", "experiment.fm.images", "experiment.quick.fm_images"),
                                ("exp5", "experiment.repetitions", "experiment.quick.repetitions")):
        s = mf.flatten(validate(make_cfg(f"experiment={exp}", "preset=quick")))
        assert mf.as_used(s, exp)[key] == s[quick_key] != s[key]
        full = mf.flatten(validate(make_cfg(f"experiment={exp}")))
        assert mf.as_used(full, exp) == full
    from neuroimagery.experiments.exp1 import protocol as exp1
    from neuroimagery.experiments.exp2 import protocol as exp2
    for exp, mod in (("exp1", exp1), ("exp2", exp2)):  # the values the experiments' own code uses
        cfg = validate(make_cfg(f"experiment={exp}", "preset=quick"))
        assert mf.as_used(mf.flatten(cfg), exp)["experiment.som.iterations"] == mod._e(cfg).som.iterations
    for exp in ("exp1", "exp2", "exp6"):  # their quick presets test fewer participants (docs/choices.md)
        assert mf.as_used(mf.flatten(validate(make_cfg(f"experiment={exp}", "preset=quick"))), exp)["participants"] == 3


@pytest.mark.parametrize("a", [[1.0, 1.0 + 1e-9], [0.0, 0.0], [0.2, 0.9], [0.5, 0.5]])
def test_images_and_figures_share_one_colour_scale(a):
    x = np.array(a)
    img = _to_image(torch.tensor(x, dtype=torch.float32))[:, 0].numpy().T  # (W, 3): the strip's first row
    k = img.shape[0] // len(a)
    tb = img[k // 2::k]  # one colour per unit
    fig = _cell(x)
    fig = fig[~np.isnan(fig).any(1)][0, np.arange(len(a)) * fig.shape[1] // len(a)]
    np.testing.assert_allclose(tb, matplotlib.colormaps[COLOUR_MAP](fig)[:, :3], atol=1e-6)


@pytest.mark.parametrize("exp", ["exp1", "exp2"])
def test_a_report_names_its_preset_in_its_first_lines(tmp_path, exp):
    evaluate(make_cfg(f"experiment={exp}", "participants=1", "progress=false", "logger=none", "preset=quick"),
             out_dir=tmp_path)
    head = "\n".join((tmp_path / "report.md").read_text().splitlines()[:4])
    assert "Preset `quick`" in head, head


def test_a_pooled_report_names_the_preset(tmp_path):
    from neuroimagery.app.pool import pool

    for seed in (0, 1):
        evaluate(make_cfg("experiment=demo", "participants=2", "progress=false", "logger=none", f"seed={seed}"),
                 out_dir=tmp_path / str(seed))
    summary, _, rep = pool([tmp_path / "0", tmp_path / "1"])
    head = "\n".join(rep.text().splitlines()[:4])
    assert summary["preset"] == "full" and "Preset `full`" in head, head
