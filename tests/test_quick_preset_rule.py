"""The quick presets of Experiments 1, 2 and 6 follow the rule of docs/choices.md ("Quick presets"):
the full protocol's training, a quarter of its participants (rounded up); every report names the
preset in its first lines. (Whether the quick runs keep the full runs' effects and rates over
seeds 0-4 is measured by the slow tests/test_quick_presets.py.)"""
import math

import pytest
from conftest import make_cfg

from neuroimagery.core import manifest as mf
from neuroimagery.config import validate
from neuroimagery.app.run import evaluate

RULED = ("exp1", "exp2", "exp6")


@pytest.mark.parametrize("exp", RULED)
def test_quick_tests_a_quarter_of_the_participants(exp):
    full = validate(make_cfg(f"experiment={exp}"))
    quick = validate(make_cfg(f"experiment={exp}", "preset=quick"))
    assert full.participants == 10 and quick.participants == math.ceil(full.participants / 4) == 3
    assert validate(make_cfg(f"experiment={exp}", "preset=quick", "participants=2")).participants == 2


@pytest.mark.parametrize("exp", RULED)
def test_quick_trains_as_the_full_protocol(exp):
    """Every setting a quick run uses equals the full run's but the participants and (Exp 6) the test objects."""
    full = mf.flatten(validate(make_cfg(f"experiment={exp}")))
    quick = mf.as_used(mf.flatten(validate(make_cfg(f"experiment={exp}", "preset=quick"))), exp)
    differ = {k for k in full if not k.startswith("experiment.quick.") and quick.get(k) != full[k]}
    assert differ <= {"preset", "participants", "experiment.objects.test"}, differ
    if exp in ("exp1", "exp2"):  # the experiments' own code: the SOM steps they train
        from neuroimagery.experiments.exp1 import protocol as exp1
        from neuroimagery.experiments.exp2 import protocol as exp2
        mod = {"exp1": exp1, "exp2": exp2}[exp]
        q, f = validate(make_cfg(f"experiment={exp}", "preset=quick")), validate(make_cfg(f"experiment={exp}"))
        assert mod._e(q).som.iterations == mod._e(f).som.iterations
    else:
        e = validate(make_cfg("experiment=exp6")).experiment
        assert (e.quick.fm_images, e.quick.chains) == (e.fm.images, e.image.chains)


TINY6 = ("experiment.grid=10", "experiment.quick.fm_images=16",
         "experiment.quick.chains=8", "experiment.quick.objects=1", "experiment.objects.train=1",
         "experiment.test_angles=[0,60,120,180]", "experiment.step_deg=30", "experiment.search.iterations=20")


def test_the_exp6_report_names_its_preset_in_its_first_lines(tmp_path):
    evaluate(make_cfg("experiment=exp6", "participants=1", "progress=false", "logger=none", "preset=quick", *TINY6),
             out_dir=tmp_path)
    head = "\n".join((tmp_path / "report.md").read_text().splitlines()[:4])
    assert "preset `quick`" in head.lower(), head


def test_a_pooled_report_of_quick_runs_names_the_preset(tmp_path):
    from neuroimagery.app.pool import pool

    for seed in (0, 1):
        evaluate(make_cfg("experiment=exp1", "participants=1", "progress=false", "logger=none", "preset=quick",
                          f"seed={seed}"), out_dir=tmp_path / str(seed))
    summary, _, rep = pool([tmp_path / "0", tmp_path / "1"])
    head = "\n".join(rep.text().splitlines()[:4])
    assert summary["preset"] == "quick" and "Preset `quick`" in head, head
